"""akarm.sim.robot.overrun: what a simulated driver whose receive buffer overflowed answers of a backlog."""

from __future__ import annotations

import can

from akarm.protocol import mit
from akarm.sim.robot import overrun

NOW = 1000.0


def frame(can_id: int, data: bytes, age: float, extended: bool = False) -> can.Message:
    return can.Message(arbitration_id=can_id, data=data, is_extended_id=extended, timestamp=NOW - age)


def cmd(position: float) -> bytes:
    return mit.encode_command("AK80-9", position, 0.0, 5.0, 0.5, 0.0)


def test_of_old_setpoints_only_the_newest_to_each_id_is_kept_in_order() -> None:
    batch = [frame(1, cmd(0.1), 0.9), frame(2, cmd(0.2), 0.9), frame(1, cmd(0.3), 0.5), frame(2, cmd(0.4), 0.5),
             frame(1, cmd(0.5), 0.1)]
    kept = overrun(batch, NOW, 0.25)
    assert [(m.arbitration_id, bytes(m.data)) for m in kept] == [(2, cmd(0.4)), (1, cmd(0.5))]


def test_enter_exit_zero_and_servo_frames_are_kept_however_old() -> None:
    servo = frame(0x401, bytes([0, 0, 0, 1]), 2.0, extended=True)
    batch = [frame(1, mit.ENTER, 2.0), frame(1, cmd(0.1), 2.0), frame(1, mit.ZERO, 2.0), servo, servo,
             frame(1, cmd(0.2), 2.0), frame(1, mit.EXIT, 2.0)]
    kept = overrun(batch, NOW, 0.25)
    assert [bytes(m.data) for m in kept] == [mit.ENTER, mit.ZERO, bytes(servo.data), bytes(servo.data), cmd(0.2),
                                              mit.EXIT]


def test_setpoints_that_waited_less_than_after_are_all_kept() -> None:
    batch = [frame(1, cmd(0.1), 0.2), frame(1, cmd(0.2), 0.1), frame(1, cmd(0.3), 0.0)]
    assert overrun(batch, NOW, 0.25) == batch
    assert len(overrun(batch, NOW, 0.15)) == 2   # the first waited 0.2 s: replaced by the last
