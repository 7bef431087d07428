"""Teach and replay: guide the arm by hand, keep keyframes and the whole path, play them back.

    .venv/bin/python examples/teach_and_replay.py                    # on the simulator (arm6)
    .venv/bin/python examples/teach_and_replay.py --hardware -c can0  # you guide the real arm
    .venv/bin/python examples/teach_and_replay.py --out taught/       # keep the recordings

In teach mode the position loop is off (kp = 0, a little damping) and the arm's weight is carried
at the measured pose, so it floats where a hand leaves it. While you guide it, `keyframe()` takes
the pose at that moment and `start_recording()` samples the whole path (here at 100 Hz). Both are
plain files (YAML keyframes, CSV path) and are checked against every joint limit before replay.

On the simulator the "hand" is an external torque on the simulated joints
(`sim.set_external_torque`), pushing the base, shoulder and wrist in turn. On hardware you move
the arm yourself and press Enter for each keyframe.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
from _setup import open_arm, parse_args, run

from akarm import LimitError
from akarm.motion import recording

# The simulated hand: (torque per joint in N·m, how long in s); a keyframe is taken after each push,
# once the arm has come to rest. arm6's joints: pan, lift, elbow, roll, wrist pitch, wrist roll.
PUSHES = [
    ([2.2, 0.0, 0.0, 0.0, 0.0, 0.0], 0.5),  # turn the base left (against 1.3 N·m of friction)
    ([0.0, 0.6, -0.4, 0.0, 0.4, 0.0], 0.5),  # lean the shoulder forward, fold the elbow, tip the wrist
    ([-2.2, 0.0, 0.0, 0.0, 0.0, 0.5], 0.5),  # turn the base back and the wrist around
]
SETTLE = 0.6  # s of no push before each keyframe


def fmt(q) -> str:
    """Joint positions (rad) as a short string."""
    return " ".join(f"{x:+.3f}" for x in q)


def guide_by_simulated_hand(arm, sim) -> list[recording.Keyframe]:
    """Push the simulated arm through PUSHES; return a keyframe after each."""
    frames = []
    for k, (tau, seconds) in enumerate(PUSHES, start=1):
        sim.set_external_torque(np.array(tau))
        arm.sleep(seconds)
        sim.set_external_torque(None)  # the hand lets go; the arm floats (gravity carried)
        arm.sleep(SETTLE)
        frames.append(arm.keyframe(f"pose{k}"))
        print(f"  keyframe pose{k}: {fmt(frames[-1].q)} rad")
    return frames


def guide_by_your_hand(arm) -> list[recording.Keyframe]:
    """Take a keyframe at each Enter; 'done' ends."""
    frames = []
    print("move the arm by hand; Enter takes a keyframe, 'done' + Enter ends")
    while True:
        answer = input(f"  keyframe {len(frames) + 1}? ").strip().lower()
        if answer == "done":
            break
        frames.append(arm.keyframe(f"pose{len(frames) + 1}"))
        print(f"  keyframe pose{len(frames)}: {fmt(frames[-1].q)} rad")
    return frames


def closest_distance(path: np.ndarray, trace: np.ndarray) -> np.ndarray:
    """For each point of ``path`` (n × joints, rad): its distance (largest joint difference, rad) to ``trace``."""
    return np.array([np.min(np.max(np.abs(trace - p), axis=1)) for p in path])


def main() -> int:
    args = parse_args("Teach arm6 by hand (simulated or real), then replay.",
                      [(("--out",), {"metavar": "DIR", "help": "keep the recordings in DIR (default: a temporary "
                                                                  "folder)"})])
    out = Path(args.out) if args.out else Path(tempfile.mkdtemp(prefix="akarm-teach-"))
    with open_arm(args, "arm6") as (arm, sim):
        arm.enable()
        arm.move_to("ready", speed=0.5)
        start = arm.state().q

        arm.teach()  # hand-guidable from here: kp = 0, damping 0.1 N·m·s/rad, weight carried
        arm.start_recording(rate_hz=100.0)
        frames = guide_by_your_hand(arm) if sim is None else guide_by_simulated_hand(arm, sim)
        path = arm.stop_recording()
        arm.end_teach()  # holds the pose the hand left, gains ramping up from zero
        if not frames:
            print("no keyframes taken: nothing to replay")
            arm.disable()
            print("disabled")
            return 0

        moved = np.abs(path.q - start).max()
        print(f"taught {len(frames)} keyframes; recorded a path of {len(path.t)} samples ({path.duration:.1f} s); "
              f"the hand moved the arm {moved:.2f} rad at most")
        keyframes = recording.Keyframes(arm.names, tuple(frames), robot=arm.config.name)
        kf_file = keyframes.save(out / "keyframes.yaml")
        path_file = path.save(out / "path.csv")
        print(f"saved {kf_file} and {path_file}")

        # Back to the start, then replay the keyframes: one smooth move through them.
        arm.move_to(start, speed=0.5)
        arm.replay(kf_file, speed=0.5)
        error = np.abs(arm.state().q - np.array(frames[-1].q)).max()
        print(f"keyframes replayed: the last one reached within {error * 1e3:.2f} mrad")

        # Back to the start, then replay the path at its recorded timing. The file is checked first:
        # a path too fast for the limits (a hand is quicker than the limits allow) raises LimitError,
        # naming the joint, the time and a speed factor that passes; nothing has moved then.
        arm.move_to(start, speed=0.5)
        for speed in (1.0, 0.5, 0.25):
            try:
                t0 = arm.clock.now()
                arm.replay(path_file, speed=speed)
                break
            except LimitError as e:
                print(f"  not at speed {speed}: {e}")
        else:
            print("the path is too fast for the limits even at speed 0.25: not replayed")
            arm.disable()
            return 1
        trace = arm.telemetry(since=t0).q  # where the arm really went, rad
        deviation = closest_distance(path.q, trace).max()
        print(f"path replayed at speed {speed}: within {deviation * 1e3:.1f} mrad of the taught path everywhere")
        arm.disable()
        print("disabled")
    return 0


if __name__ == "__main__":
    run(main)
