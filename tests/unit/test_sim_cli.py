"""`akarm sim`'s status line and its refusal of a fault on an unknown joint (the simulator running:
tests/system/test_sim_cli.py)."""

from __future__ import annotations

import pytest

from akarm.cli import main

from .conftest import ROBOTS

PLANAR2 = str(ROBOTS / "planar2.yaml")


def test_cli_rejects_a_fault_on_an_unknown_joint(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["sim", PLANAR2, "-i", "virtual", "-c", "unused", "--fault", "wrist:drop:0.1"]) == 1
    assert "no joint named 'wrist'" in capsys.readouterr().err


@pytest.mark.parametrize(("args", "says"), [
    (["--serial", "pan"], "bad --serial 'pan': expected JOINT=PATH"),
    (["--serial", "pan=pty", "--serial", "pan=/dev/ttyUSB0"], "--serial gives joint 'pan' twice"),
    (["--serial", "wrist=pty"], "no joint named 'wrist'"),
])
def test_cli_rejects_bad_serial_options(capsys: pytest.CaptureFixture[str], args: list[str], says: str) -> None:
    assert main(["sim", str(ROBOTS / "servo3.yaml"), "-i", "virtual", "-c", "unused", *args]) == 1
    err = capsys.readouterr().err
    assert says in err and "Traceback" not in err


def test_status_line_fits_80_columns_or_is_wrapped_per_joint() -> None:
    from akarm.cli.sim import status_block

    short = "t=    1.00s | a +0.000rad +0.00Nm  25.0C on"
    assert status_block(short, 80) == [short]
    six = "t=    1.00s | " + " | ".join(f"joint{k} +0.000rad +0.00Nm  25.0C on" for k in range(6))
    block = status_block(six, 80)
    assert block[0] == "t=    1.00s" and len(block) == 7
    assert all(len(line) < 80 for line in block) and block[3] == "  joint2 +0.000rad +0.00Nm  25.0C on"
    assert all(len(line) < 20 for line in status_block(six, 20))  # a very narrow terminal: cut
