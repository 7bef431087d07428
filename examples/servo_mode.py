"""Servo mode: the same Arm API on motors whose own firmware closes the position loop.

    .venv/bin/python examples/servo_mode.py                    # on the simulator (servo3)
    .venv/bin/python examples/servo_mode.py --hardware -c can0  # on the real arm

In servo mode (robots/servo3.yaml: `mode: servo`) the Arm sends each motor one position command
per cycle, sampled from the same jerk-limited trajectory as in MIT mode, and each motor answers
with status frames at its own rate (`status_rate_hz`, set in the motor with CubeMars' tool). There
are no kp/kd to tune on the Arm's side, and no torque feed-forward: the drive's loop does the work.
A pick-and-place cycle: home → pick → place → home.
"""

from __future__ import annotations

import numpy as np
from _setup import open_arm, parse_args, run


def main() -> int:
    args = parse_args("Servo-mode pick and place on servo3.")
    with open_arm(args, "servo3") as (arm, _sim):
        for j in arm.config.joints:
            print(f"  {j.name}: {j.motor.name}, {j.mode} mode, CAN ID {j.can_id}, status frames at "
                  f"{j.status_rate_hz:g} Hz, direction {j.direction:+d}")
        arm.enable()  # servo joints: hold the position their status frames report
        print("enabled")
        for pose in ("home", "pick", "place", "home"):
            t0 = arm.clock.now()
            motion = arm.move_to(pose)
            arm.sleep(0.2)
            error = np.abs(arm.state().q - np.array(arm.config.pose(pose)))
            lag = np.abs(arm.telemetry(since=t0).tracking_error()).max()
            print(f"  {pose:<6} {motion.duration:5.2f} s; largest lag while moving {lag * 1e3:5.1f} mrad, "
                  f"then {error.max() * 1e3:5.2f} mrad from the pose")
        print(arm.state())
        arm.disable()  # servo joints: a braking current, then released
        print("disabled")
    return 0


if __name__ == "__main__":
    run(main)
