"""The reply router: a cycle's drained frames routed in one call (route_frames) land exactly where
routing them one by one (route_frame) puts them, whatever the frame."""

from __future__ import annotations

import math
from dataclasses import replace

import akarm
from akarm.control.joints import Router, make_joint
from akarm.protocol import mit, servo

from .conftest import ROBOTS

_KEPT = ("position", "velocity", "torque", "temperature", "error", "stamp")


def _joints():
    mits = akarm.load_robot(ROBOTS / "arm6.yaml").joints[:3]  # CAN IDs 1-3
    servos = [replace(j, can_id=j.can_id + 10) for j in akarm.load_robot(ROBOTS / "servo3.yaml").joints[:2]]
    return [make_joint(i, c) for i, c in enumerate([*mits, *servos])]


def _value(v):
    # NaN equals itself in a list only as the same object; a compiled router makes a new one each time
    return "nan" if isinstance(v, float) and math.isnan(v) else v


def _snapshot(router: Router, joints) -> list:
    return [router.unrouted, router.corrupt] + [
        (tuple(_value(getattr(j.state, k)) for k in _KEPT), j.frames_received, j.rejected, j.foreign, j.foreign_at,
         getattr(j, "mode_seen", None)) for j in joints]


def _frames() -> list[tuple[float, list[tuple[int, bool, bool, int, bytes]]]]:
    codec = mit.MitCodec("AK80-9")
    r1 = codec.encode_reply(1, 0.5, 1.0, 2.0)
    r2 = codec.encode_reply(2, -0.25, -0.5, 0.75, length=6)
    own = codec.encode_reply(3, 0.1, 0.0, 0.0)  # on joint 3's own command ID (some units answer so)
    arb, status = servo.encode_status(11, 12.5, 300.0, 1.5, 30.0)
    jump = codec.encode_reply(1, 0.5 + 6.0, 0.0, 0.0)  # 6 rad in 2 ms: the gate refuses it
    foreign = bytes([0x09]) + r1[1:]  # 8 bytes on joint 1's command ID, byte 0 not its own: another node's
    return [
        (1.000, [(0x0, False, True, 8, r1), (0x0, False, True, 6, r2), (3, False, True, 8, own),
                 (arb, True, True, 8, status)]),
        (1.002, [(0x0, False, True, 8, jump), (1, False, True, 8, mit.ENTER), (2, False, True, 8, foreign),
                 (0x0, False, True, 5, r1[:5]), (0x0, False, True, 8, codec.encode_reply(42, 0.0, 0.0, 0.0)),
                 (0x0, False, False, 0, b""), ((servo.ServoPacket.STATUS << 8) | 1, True, True, 8, status),
                 (0x7FF, True, True, 8, status)]),
        (1.004, [(0x0, False, True, 8, codec.encode_reply(1, 0.52, 1.0, 2.0))]),
    ]


def test_route_frames_routes_every_kind_of_frame_as_route_frame_does():
    one_by_one, batched = _joints(), _joints()
    for js in (one_by_one, batched):
        for j in js:
            j.set_gate(max_speed=50.0, min_interval=1e-3)
            j.begin_contact()
    r1, r2 = Router(one_by_one), Router(batched)
    for now, frames in _frames():
        for f in frames:
            r1.route_frame(*f, now)
        r2.route_frames(frames, now)
        assert _snapshot(r2, batched) == _snapshot(r1, one_by_one)
    # and the frames did what they should: replies taken, the jump refused, the others noted or counted
    j1, j2, j3, s1 = batched[0], batched[1], batched[2], batched[3]
    assert j1.frames_received == 3 and j1.rejected == 1
    assert abs(j1.state.position - j1.joint_position(0.52)) < 1e-3 and j1.state.stamp == 1.004
    assert j2.state.temperature is None and j2.state.stamp == 1.0  # the 6-byte reply has none
    assert j3.state.stamp == 1.0
    assert j1.foreign == "enter" and j2.foreign == "command"
    assert s1.state.stamp == 1.0 and j1.mode_seen == "servo"
    # 5 bytes, driver 42, a remote frame, an extended ID nobody has, and the MIT joint's servo status (noted)
    assert r2.unrouted == 5
