"""Servo joints over UART with the simulator in a process of its own (``akarm sim --serial JOINT=pty``, real
time), through the test rig and through the pytest plugin's ``--akarm-serial``; the line's faults in
their ``--fault`` text form. The lock-step runs: tests/sim/test_uart_arm.py."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from akarm import BusLost, UartBadCrc
from akarm.testing.rig import SimulatedArm

from .conftest import ROBOTS
from .test_testing_plugin import pytest_in

SERVO3 = ROBOTS / "servo3.yaml"


def test_akarm_sim_serial_pty_in_its_own_process_drives_pan_over_uart() -> None:
    with SimulatedArm.start(SERVO3, "akarm_local", timing="slow", serial=["pan"], pose="home") as rig:
        port = rig.process.serial_ports["pan"]
        assert port.startswith("/dev/pts/")
        assert rig.config.buses[rig.config.joint("pan").bus].channel == port
        with rig.arm() as arm:
            arm.enable()
            arm.move_to("pick")
            arm.sleep(0.5)
            assert np.allclose(arm.state().q, arm.config.pose("pick"), atol=0.02)
            rig.inject("pan", "bad-crc")  # the --fault text form, through the control channel
            with pytest.raises(BusLost) as e:
                arm.sleep(3.0)
            assert isinstance(e.value.__cause__, UartBadCrc) and e.value.bus == "uart-pan"
        rig.clear_faults()
        assert rig.enabled_joints() == []  # the stop's release still reached pan over the line


PLUGIN_TEST = """\
import numpy as np


def test_pan_runs_over_uart(akarm_sim):
    with akarm_sim.arm() as arm:
        assert arm.config.buses[arm.config.joint("pan").bus].interface == "akarm_uart"
        arm.enable()
        arm.move_to("pick")
        arm.sleep(0.5)
        assert np.allclose(arm.state().q, arm.config.pose("pick"), atol=0.02)
"""


@pytest.mark.parametrize("transport", ["virtual", "akarm_local"])
def test_the_plugins_akarm_serial_option(tmp_path: Path, transport: str) -> None:
    for name in ("servo3.yaml", "servo3.urdf"):
        (tmp_path / name).write_text((ROBOTS / name).read_text())
    (tmp_path / "test_uart.py").write_text(PLUGIN_TEST)
    r = pytest_in(tmp_path, "--akarm-robot", "servo3.yaml", "--akarm-interface", transport, "--akarm-serial", "pan",
                  *(["--akarm-profile", "slow"] if transport != "virtual" else []))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "1 passed" in r.stdout and "serial pan" in r.stdout  # the report header names it
