"""The collision reflex over long lock-step runs, several simulated seconds to a minute each: fast
moves with payload changes and the demo recording, moves retargeted mid-way, a stick streaming
targets: none is taken for a collision (detection and reactions: tests/sim/test_collision.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

import akarm
from akarm.arm import Arm

from ..sim.test_collision import THRESHOLDS, lockstep


def test_no_stop_in_fast_moves_payload_changes_and_the_demo_recording(channel: str) -> None:
    """With arm6.yaml's thresholds: moves at full speed between every pose, a payload picked up and
    put down (told to the arm), and the demo's figure eight; the reflex must not fire."""
    with lockstep(channel, telemetry_seconds=120) as (arm, sim):
        arm.reset_collision_peak()
        for pose in ("ready", "left", "reach", "upright", "home", "reach", "ready"):
            arm.move_to(pose)
        arm.set_payload(0.4, (0.0, 0.0, 0.05))
        sim.set_payload(0.4, (0.0, 0.0, 0.05))
        arm.move_through(["ready", "left", "reach", "home"])
        arm.clear_payload()
        sim.clear_payload()
        arm.replay(Path(akarm.__file__).parent / "data" / "demo_path.csv")
        assert arm.last_collision is None and arm.enabled
        ratio = arm.collision_peak / np.array(THRESHOLDS)
        assert np.all(ratio < 1.0), ratio  # not even before the reflex armed


def _within_range_and_limits(arm: Arm, log) -> None:
    lo, hi = arm.limits.lower, arm.limits.upper
    beyond = np.maximum(lo - log.q_des, log.q_des - hi).max(axis=0)
    assert np.all(beyond <= 1e-9), f"commanded past a joint's range by {beyond.max() * 1e3:.1f} mrad"
    fastest = np.abs(log.dq_des).max(axis=0) / arm.limits.velocity
    assert np.all(fastest <= 1.0 + 1e-6), f"commanded {fastest.max():.2f} times a joint's velocity limit"


def test_moves_retargeted_mid_way_stay_in_range_and_are_never_taken_for_a_collision(channel: str) -> None:
    """Random targets over the whole range, each retargeted after a random share of the last move, at
    a random speed factor (a user streaming targets). ruckig's own extrema miss a reversal at constant
    acceleration: such paths ran up to 21 mrad past a range, into the simulated hard stop, and the
    reflex rightly stopped the arm (26.6 s into this run)."""
    rng = np.random.default_rng(0)
    with lockstep(channel, telemetry_seconds=60) as (arm, sim):
        arm.reset_collision_peak()
        lo, hi = arm.limits.lower + 0.02, arm.limits.upper - 0.02
        moves = 0
        while sim.t < 30.0:
            try:
                motion = arm.move_to(rng.uniform(lo, hi), speed=float(rng.uniform(0.3, 1.0)), wait=False)
            except akarm.LimitError:  # a path that would leave the range: refused, the last move goes on
                continue
            moves += 1
            arm.sleep(float(rng.uniform(0.1, 0.8)) * motion.duration)
        assert moves >= 25 and arm.last_collision is None and arm.enabled
        _within_range_and_limits(arm, arm.telemetry())
        ratio = arm.collision_peak / np.array(THRESHOLDS)
        assert np.all(ratio < 0.6), ratio


def test_a_stick_streaming_targets_at_changing_speeds_is_followed_within_the_limits(channel: str) -> None:
    """``stream_to`` every 10-50 ms, to a noisy sweep over nearly the whole range, at speed factors
    0.3, 0.6 or 1 (a joystick with a speed button). A retarget to a slower speed first settles at
    the joints' own limits: planned at the slower ones instead, 36 % of these targets were refused
    (paths of hundreds of rad) and the rest commanded up to 1.4 times a joint's velocity limit."""
    rng = np.random.default_rng(0)
    # (the sweep folds the elbow to 98 % of its range, where arm6's forearm meets its upper arm: the
    # self-collision check, on by default, would refuse those targets; this is about ranges and the reflex)
    with lockstep(channel, telemetry_seconds=60, self_collision=False) as (arm, sim):
        arm.reset_collision_peak()
        lo, hi = arm.limits.lower, arm.limits.upper
        mid, half = (lo + hi) / 2, (hi - lo) / 2
        freq, phase = rng.uniform(0.1, 0.6, 6), rng.uniform(0.0, 2 * np.pi, 6)
        t0 = sim.t
        streamed = 0
        while sim.t - t0 < 12.0:
            stick = mid + 0.98 * half * np.sin(2 * np.pi * freq * (sim.t - t0) + phase) + rng.normal(0.0, 0.05, 6)
            arm.stream_to(np.clip(stick, lo, hi), speed=float(rng.choice([0.3, 0.6, 1.0])))  # never refused
            streamed += 1
            arm.sleep(0.01 * int(rng.integers(1, 6)))
        assert streamed > 300 and arm.last_collision is None and arm.enabled
        log = arm.telemetry()
        _within_range_and_limits(arm, log)
        assert np.abs(log.tracking_error()).max() < 0.05  # the arm follows its commands closely
        assert np.all(arm.collision_peak / np.array(THRESHOLDS) < 0.6)
