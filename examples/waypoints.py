"""Waypoints: one smooth motion through several poses, without stopping at the ones in between.

    .venv/bin/python examples/waypoints.py                    # on the simulator (arm6)
    .venv/bin/python examples/waypoints.py --hardware -c can0  # on the real arm

`move_through` plans one jerk-limited trajectory that passes every intermediate point exactly (position,
velocity and acceleration stay continuous) and ends at rest on the last one. The whole path is
checked against every joint's limits before anything moves.
"""

from __future__ import annotations

import numpy as np
from _setup import open_arm, parse_args, run


def main() -> int:
    args = parse_args("Move arm6 through waypoints without stopping.")
    with open_arm(args, "arm6") as (arm, _sim):
        arm.enable()
        arm.move_to("home", speed=0.5)

        # Waypoints can be pose names, joint vectors (rad, the YAML's joint order) or {joint: rad}
        # mappings (joints not named keep their commanded position at the time of the call).
        waypoints = [
            "ready",
            [0.6, 0.5, 1.0, 0.5, -0.4, 0.8],
            "left",
            {"shoulder_pan": -0.5, "wrist_roll": -0.8},
            "home",
        ]
        t0 = arm.clock.now()
        motion = arm.move_through(waypoints, speed=0.8)
        print(f"moved through {len(waypoints)} waypoints in {motion.duration:.2f} s (speed 0.8)")

        # Did it really pass them without stopping? Look in the telemetry: for each waypoint, the
        # commanded position closest to it, and how fast the arm was commanded to move there.
        log = arm.telemetry(since=t0)
        for k, segment in enumerate(motion.plan.segments):
            target = segment.end[0]  # where this segment of the plan ends, rad
            i = int(np.argmin(np.max(np.abs(log.q_des - target), axis=1)))
            miss = np.max(np.abs(log.q_des[i] - target)) * 1e3
            speed = np.max(np.abs(log.dq_des[i]))
            print(f"  waypoint {k + 1}: passed within {miss:.2f} mrad, fastest joint there {speed:.2f} rad/s")
        print(f"tracking error over the motion: RMS per joint {np.round(log.rms_error() * 1e3, 2)} mrad")
        arm.disable()
        print("disabled")
    return 0


if __name__ == "__main__":
    run(main)
