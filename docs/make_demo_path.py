"""Generate ``akarm/data/demo_path.csv``: the continuous recording ``akarm demo`` replays on arm6.

Run from the repository root (it rewrites the file and checks it)::

    .venv/bin/python docs/make_demo_path.py

The path is two laps of a figure eight drawn by the tool in front of the ``ready`` pose: the base
sweeps side to side once per lap (``sin φ``) while shoulder and elbow rise and fall twice
(``sin 2φ``), and the wrist joints nod and turn along. The phase φ(t) follows a quintic
(minimum-jerk) profile from 0 to 4π, so the path starts and ends at rest on ``ready`` with zero
velocity and acceleration. Samples at 100 Hz, as ``akarm teach --continuous`` would record them.

Before writing, the script checks the path exactly as :meth:`akarm.Arm.replay` does at speed 1
(smoothed, then position, velocity, acceleration and jerk against every joint's limits) and prints
each joint's peak use of its limits.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from akarm.arm import Arm  # noqa: E402
from akarm.motion import recording  # noqa: E402
from akarm.robotfile.load import load_robot  # noqa: E402

DURATION = 7.0  # s
RATE = 100.0  # Hz
LAPS = 2
#: amplitude per joint (rad) and whether it follows sin φ (1) or sin 2φ (2), arm6's joint order
AMPLITUDE = np.array([0.55, 0.18, -0.22, 0.35, 0.30, 0.60])
HARMONIC = np.array([1, 2, 2, 1, 2, 1])
OUTPUT = ROOT / "akarm" / "data" / "demo_path.csv"


def phase(t: np.ndarray) -> np.ndarray:
    """φ(t), rad: a quintic from 0 to 2π·LAPS over DURATION, at rest (φ' = φ'' = 0) at both ends."""
    s = np.clip(t / DURATION, 0.0, 1.0)
    return 2 * np.pi * LAPS * (10 * s**3 - 15 * s**4 + 6 * s**5)


def make(start: np.ndarray, names: tuple[str, ...]) -> recording.PathRecording:
    """The recording: positions (rad) around ``start`` at RATE Hz for DURATION s."""
    t = np.arange(0.0, DURATION + 1e-9, 1.0 / RATE)
    phi = phase(t)[:, None]
    q = start[None, :] + AMPLITUDE[None, :] * np.sin(HARMONIC[None, :] * phi)
    return recording.PathRecording(names, t, q)


def main() -> int:
    """Write and check the recording; 0 when it passes replay's limit check at speed 1."""
    config = load_robot(ROOT / "robots" / "arm6.yaml")
    arm = Arm(config)  # only for its limits: nothing is opened
    rec = make(np.array(config.pose("ready")), config.joint_names)
    plan = recording.PathPlan(rec, 0.0, 1.0)
    recording.check_path(plan, arm.limits)  # raises LimitError, naming the joint, if it would not replay
    lim = arm.limits
    print(f"{'joint':<14}{'range rad':>18}{'vel %':>8}{'acc %':>8}{'jerk %':>8}")
    for k, name in enumerate(config.joint_names):
        lo, hi = plan.q[:, k].min(), plan.q[:, k].max()
        use = [100 * np.abs(a[:, k]).max() / m[k] for a, m in ((plan.dq, lim.velocity),
                                                                (plan.ddq, lim.acceleration), (plan.jerk, lim.jerk))]
        print(f"{name:<14}{lo:9.3f}{hi:9.3f}{use[0]:8.0f}{use[1]:8.0f}{use[2]:8.0f}")
    rec.save(OUTPUT)
    back = recording.load(OUTPUT, config.joint_names)
    assert isinstance(back, recording.PathRecording)
    recording.check_path(recording.PathPlan(back, 0.0, 1.0), lim)
    print(f"wrote {OUTPUT.relative_to(ROOT)}: {len(back.t)} samples, {back.duration:.2f} s; passes at speed 1")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
