"""The server's parts on their own: the bus registry and the CLI's control socket."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

import akarm
from akarm.errors import AkarmError, LimitError, MotorFault, StateError
from akarm.server import registry
from akarm.server.control import ControlClient, ControlServer

from .conftest import ROBOTS


def config_on(channel: str, interface: str = "akarm_local"):
    return akarm.load_robot(ROBOTS / "planar2.yaml").with_bus(interface=interface, channel=channel)


def test_a_bus_lock_is_exclusive_across_processes_and_gone_with_its_holder(channel):
    config = config_on(channel)
    assert registry.find_server(config) is None
    holder = subprocess.Popen([sys.executable, "-c", f"""
import sys, akarm
from akarm.server.registry import BusLock
lock = BusLock(akarm.load_robot({str(ROBOTS / 'planar2.yaml')!r}).with_bus(interface="akarm_local",
               channel={channel!r}), {{"robot": "planar2", "socket": "/nowhere"}})
print("locked", flush=True)
sys.stdin.readline()
"""], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        info = registry.find_server(config)
        assert info is not None and info["pid"] == holder.pid and info["socket"] == "/nowhere"
        with pytest.raises(StateError, match=f"pid {holder.pid}.*two controllers"):
            registry.BusLock(config, {"robot": "again"})
        with pytest.raises(StateError, match="opening this Arm would be a second controller"):
            akarm.Arm(config).open()
    finally:
        holder.kill()  # no clean exit: the kernel drops the lock anyway
        holder.wait()
    assert registry.find_server(config) is None
    lock = registry.BusLock(config, {"robot": "mine"})
    try:
        assert registry.find_server(config) is None, "this process's own server does not count"
    finally:
        lock.release()


def test_virtual_buses_are_never_locked(channel):
    assert registry.bus_keys(config_on(channel, "virtual")) == []
    assert registry.bus_keys(config_on("vcan0", "socketcan")) == ["socketcan-vcan0"]


def test_the_control_socket_carries_results_and_the_servers_errors(tmp_path):
    def dispatch(op, args):
        if op == "add":
            return args["a"] + args["b"]
        if op == "limit":
            raise LimitError("past the range", joint="elbow", fix="a smaller target")
        if op == "fault":
            raise MotorFault("over-temperature", code=1, joint="elbow", fix="let it cool")
        raise KeyError(op)

    server = ControlServer(tmp_path / "c.sock", dispatch)
    try:
        with ControlClient(tmp_path / "c.sock", timeout=10) as c:
            assert c.call("add", a=2, b=3) == 5
            with pytest.raises(LimitError) as e:
                c.call("limit")
            assert (e.value.joint, e.value.fix) == ("elbow", "a smaller target")
            assert str(e.value) == str(LimitError("past the range", joint="elbow", fix="a smaller target"))
            with pytest.raises(akarm.SafetyStop, match="over-temperature"):  # its own constructor: the parent class
                c.call("fault")
            with pytest.raises(AkarmError, match="server error: KeyError"):
                c.call("nonsense")
            assert c.call("add", a=1, b=1) == 2, "the connection survives an error"
    finally:
        server.close()
    assert not (tmp_path / "c.sock").exists()
    with pytest.raises(StateError, match="cannot reach akarm serve"):
        ControlClient(tmp_path / "c.sock")


def test_the_lock_files_live_in_one_place_whatever_the_environment(monkeypatch, tmp_path):
    first = registry.runtime_dir()
    monkeypatch.setenv("XDG_RUNTIME_DIR", str(tmp_path))
    assert registry.runtime_dir() == first and first.name == f"akarm-{os.getuid()}"
    assert (first.stat().st_mode & 0o777) == 0o700
