"""What went over the wire, as the motors saw it: a spy on every bus of a robot, and the checks that the
controller left every joint damped and then disabled.

The spy is one more python-can bus per configured bus (virtual or akarm_local), so it hears the
controller's frames and the drivers' replies alike. In real time (another process) a thread drains
it continuously (an akarm_local ring holds 512 frames: a sixth of a second of arm6 at 500 Hz).
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass

import can

from akarm.config import JointConfig, RobotConfig
from akarm.control.controller import RELEASES
from akarm.protocol import mit, servo


@dataclass(frozen=True)
class Sent:
    """A frame the controller sent to one joint, decoded: ``kind`` is ``"enter"``, ``"exit"``,
    ``"zero"`` or ``"command"`` (MIT: ``kp``, ``kd``, ``torque``), or a servo packet name
    (``"SET_POS_SPD"``, ``"SET_CURRENT"``, ``"SET_CURRENT_BRAKE"``, ...; ``value``: its first value)."""

    t: float
    kind: str
    kp: float = 0.0
    kd: float = 0.0
    torque: float = 0.0
    value: float = 0.0


class Wire:
    """Every frame on a robot's buses, from now on (a ``with`` block).

    Args:
        config: the robot, with the bus override in force (the channels to listen to).
        background: drain the buses on a thread (real time); else call :meth:`drain`.
    """

    def __init__(self, config: RobotConfig, background: bool = False) -> None:
        self.config = config
        self.realtime = background
        self.frames: list[tuple[str, can.Message]] = []
        self._buses = {name: can.Bus(interface=b.interface, channel=b.channel) for name, b in config.buses.items()}
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._thread: threading.Thread | None = None
        if background:
            self._thread = threading.Thread(target=self._run, daemon=True)
            self._thread.start()

    def _run(self) -> None:
        while not self._stop.is_set():
            self.drain()
            time.sleep(0.002)

    def drain(self) -> list[tuple[str, can.Message]]:
        """Take in what arrived; return all frames so far."""
        with self._lock:
            for name, bus in self._buses.items():
                while (msg := bus.recv(0.0)) is not None:
                    msg.timestamp = time.time() if not msg.timestamp else msg.timestamp
                    self.frames.append((name, msg))
            return list(self.frames)

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(2.0)
        self.drain()
        for bus in self._buses.values():
            bus.shutdown()

    def __enter__(self) -> Wire:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def sent_to(self, joint: JointConfig) -> list[Sent]:
        """The frames sent to ``joint`` (its command IDs on its bus), in order, decoded."""
        out = []
        for name, m in self.drain():
            if name != joint.bus:
                continue
            data = bytes(m.data)
            if joint.mode == "mit" and joint.firmware == "v2":
                if m.is_extended_id or m.arbitration_id != joint.can_id or len(data) != 8:
                    continue
                if data[0] == joint.can_id and joint.reply_id == joint.can_id:
                    continue  # its reply on its own ID
                special = mit.special_frame(data)
                if special is not None:
                    out.append(Sent(m.timestamp, special))
                else:
                    c = mit.decode_command(joint.motor, data)
                    out.append(Sent(m.timestamp, "command", c.kp, c.kd, c.torque))
            elif joint.mode == "servo":
                if not m.is_extended_id or m.arbitration_id & 0xFF != joint.can_id or m.arbitration_id >> 8 == 0x29:
                    continue
                cmd = servo.decode_command(m.arbitration_id, data)
                out.append(Sent(m.timestamp, cmd.packet.name, value=cmd.values[0]))
        return out


def damping_then_exit(wire: Wire, config: RobotConfig, damping_time: float = 0.3) -> dict[str, int]:
    """Assert that every joint's last frames were damping (MIT: kp = 0, kd > 0; servo: a braking
    current) for about ``damping_time`` s, then the exit frames (MIT: a zero-gain, zero-torque
    command, then EXIT; servo: zero current) on :data:`~akarm.control.controller.RELEASES` cycles, and
    nothing after them. Returns the damping frames
    per joint.

    In lock step the damping is counted in frames (one per cycle); in real time it is timed from the
    frames' stamps (a loaded machine makes the loop skip slots rather than send bursts)."""
    counts = {}
    want = int(damping_time * config.rate_hz) - 2
    for j in config.joints:
        sent = wire.sent_to(j)
        assert sent, f"nothing was sent to {j.name}"
        # the exit (MIT: a zero-gain, zero-torque command, then EXIT; servo: zero current), on RELEASES cycles
        end = len(sent)
        if j.mode == "mit":
            lsb = 2.0 * j.motor.t_max / 4095  # zero torque, to the 12-bit field's step
            for _ in range(RELEASES):
                neutral = sent[end - 2]
                assert sent[end - 1].kind == "exit", (j.name, sent[-3 * RELEASES:])
                assert (neutral.kind, neutral.kp, neutral.kd, abs(neutral.torque) <= lsb) == \
                    ("command", 0.0, 0.0, True), (j.name, neutral)
                end -= 2
            k = end - 1
            while k >= 0 and sent[k].kind == "command" and sent[k].kp == 0.0 and sent[k].kd > 0.0:
                k -= 1
        else:
            for _ in range(RELEASES):
                assert (sent[end - 1].kind, sent[end - 1].value) == ("SET_CURRENT", 0.0), (j.name, sent[-3:])
                end -= 1
            k = end - 1
            while k >= 0 and sent[k].kind == "SET_CURRENT_BRAKE":
                k -= 1
        damped = end - 1 - k
        if wire.realtime:
            first, last = sent[k + 1].t, sent[k + damped].t
            assert damped >= 2 and last - first >= damping_time - 3.0 / config.rate_hz - 0.005, \
                f"{j.name}: damped for {last - first:.3f} s before the exit, expected {damping_time} s"
        else:
            assert damped >= want, f"{j.name}: {damped} damping frames before the exit, expected {want} or more"
        counts[j.name] = damped
    return counts


def never_held(wire: Wire, config: RobotConfig) -> None:
    """Assert that no joint was ever given stiffness (kp > 0) and that each MIT joint's last frame is EXIT
    (or that nothing at all was sent to it)."""
    for j in config.joints:
        sent = wire.sent_to(j)
        assert all(s.kp == 0.0 for s in sent), (j.name, [s for s in sent if s.kp])
        if j.mode == "mit" and sent:
            assert sent[-1].kind == "exit", (j.name, sent[-3:])
