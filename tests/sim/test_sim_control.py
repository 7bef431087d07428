"""The simulator's control channel (akarm sim --control): faults as JSON, requests and refusals.

The server is run around an in-process, lock-step SimulatedRobot (the protocol is the same as in
``akarm sim``); tests/system/test_sim_rig.py drives it in a simulator of its own process.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from akarm import AkarmError, StateError, load_robot
from akarm.sim import SimulatedRobot, faults
from akarm.sim.channel import CATCH_UP, ChannelServer, SimulatorControl

from .conftest import ROBOTS


@pytest.fixture
def served(channel: str, tmp_path: Path) -> Iterator[tuple[SimulatedRobot, SimulatorControl]]:
    config = load_robot(ROBOTS / "planar2.yaml").with_bus(interface="virtual", channel=channel)
    path = tmp_path / "sim.sock"
    with SimulatedRobot(config, realtime=False) as sim, ChannelServer(sim, path):
        yield sim, SimulatorControl(path)
    assert not path.exists()  # closing the server removed its socket


def test_inject_read_clear_and_disable_through_the_channel(served: tuple[SimulatedRobot, SimulatorControl]) -> None:
    sim, ctl = served
    ctl.inject("elbow", faults.DropReplies(0.5, seed=3))
    ctl.inject("shoulder", "error:5")                      # the --fault text
    assert sim.joint("elbow").faults == (faults.DropReplies(0.5, seed=3),)
    assert sim.joint("shoulder").error == 5
    states = {s.name: s for s in ctl.state()}
    assert states["elbow"].faults == ("DropReplies(fraction=0.5, seed=3)",) and states["shoulder"].error == 5
    ctl.clear_faults("elbow")
    assert sim.joint("elbow").faults == () and sim.joint("shoulder").error == 5
    ctl.clear_faults()
    assert sim.joint("shoulder").error == 0
    sim.joint("shoulder").enabled = True                   # as after an ENTER
    assert [s.enabled for s in ctl.state()] == [True, False]
    assert ctl.disable_drivers() == ["shoulder"]
    assert not sim.joint("shoulder").enabled
    assert ctl.disable_drivers() == []


def test_a_refused_request_says_why_and_changes_nothing(served: tuple[SimulatedRobot, SimulatorControl]) -> None:
    sim, ctl = served
    with pytest.raises(AkarmError, match="no joint named 'wrist'"):
        ctl.inject("wrist", faults.Unplugged())
    with pytest.raises(AkarmError, match="unknown kind 'melt'"):
        ctl.inject("elbow", "melt")
    with pytest.raises(AkarmError, match="unknown request"):
        ctl.request(cmd="explode")
    assert all(d.faults == () for d in sim.drivers)


def test_a_simulator_behind_its_frames_refuses_to_read_the_drivers_rather_than_answer_stale(
        served: tuple[SimulatedRobot, SimulatorControl], monkeypatch: pytest.MonkeyPatch) -> None:
    # in real time a backlog of frames (EXITs among them) may wait in the bus's queue: the drivers'
    # state before them would say "still enabled" of a motor that was told to stop
    sim, ctl = served
    sim.joint("shoulder").enabled = True
    waited: list[float] = []
    monkeypatch.setattr(sim, "wait_received", lambda timeout: waited.append(timeout) or False)
    for request in (ctl.state, ctl.disable_drivers, lambda: ctl.frames()):
        with pytest.raises(AkarmError, match="has not taken in the frames sent to it within 20 s: it cannot keep up"):
            request()
    assert waited == [CATCH_UP] * 3 and ctl.timeout > CATCH_UP
    assert sim.joint("shoulder").enabled  # the refused disable changed nothing


def test_garbage_on_the_socket_is_answered_and_the_channel_keeps_working(
        served: tuple[SimulatedRobot, SimulatorControl]) -> None:
    sim, ctl = served
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.settimeout(10.0)
        s.connect(str(ctl.path))
        s.sendall(b"not json\n[1, 2]\n")
        with s.makefile("rb") as f:
            first, second = json.loads(f.readline()), json.loads(f.readline())
    assert first["ok"] is False and "JSONDecodeError" in first["error"]
    assert second["ok"] is False and "unknown request" in second["error"]
    assert [s.name for s in ctl.state()] == ["shoulder", "elbow"]


def test_a_second_simulator_cannot_take_a_served_socket_but_a_stale_one_is_reused(
        served: tuple[SimulatedRobot, SimulatorControl], tmp_path: Path) -> None:
    sim, ctl = served
    with pytest.raises(StateError, match="another simulator serves"):
        ChannelServer(sim, ctl.path)
    stale = tmp_path / "stale.sock"
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as s:
        s.bind(str(stale))                                 # bound, never listening: what a killed simulator leaves
    with ChannelServer(sim, stale):
        assert len(SimulatorControl(stale).state()) == 2


def test_push_sets_the_external_torque_on_the_arm(served: tuple[SimulatedRobot, SimulatorControl]) -> None:
    sim, ctl = served
    q0 = sim.q.copy()
    sim.run_for(0.2)  # limp: gravity alone
    unpushed = sim.q - q0
    sim.set_state(q0)
    ctl.push([0.0, 0.4])
    sim.run_for(0.2)
    assert (sim.q - q0)[1] - unpushed[1] > 0.01  # the push turns the elbow its way
    sim.set_state(q0)
    ctl.push(None)
    sim.run_for(0.2)
    assert np.allclose(sim.q - q0, unpushed, atol=1e-9)  # and no more
    with pytest.raises(AkarmError, match="external torque must be 2 finite numbers"):
        ctl.push([1.0])
    with pytest.raises(AkarmError, match="external torque must be 2 finite numbers"):
        ctl.push([0.0, float("nan")])
