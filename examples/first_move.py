"""First move: enable the arm without a kick, move it to a named pose and back, disable it.

    .venv/bin/python examples/first_move.py                    # on the simulator (arm6)
    .venv/bin/python examples/first_move.py --hardware -c can0  # on the real arm

On hardware, the first time: low gains in the YAML, a clear workspace, the e-stop in reach.
"""

from __future__ import annotations

import numpy as np
from _setup import open_arm, parse_args, run


def main() -> int:
    args = parse_args("Enable arm6, move to 'ready' and back, disable.")
    # `with`: leaving the block in any way (the end, an exception, Ctrl-C) damps and disables the arm.
    with open_arm(args, "arm6") as (arm, _sim):
        # enable(): enter motor mode, take the measured position as the commanded one, ramp the gains
        # up from zero: the arm does not move. It raises FeedbackTimeout, naming the joint, if one is silent.
        arm.enable()
        start = arm.state().q  # measured joint positions, rad, in the YAML's joint order
        print("enabled; holding where it is:")
        print(arm.state())  # a table: position, velocity, torque, temperature, fault, feedback age

        # A named pose from the YAML's `poses:`, at half the joint limits (velocity, acceleration, jerk).
        motion = arm.move_to("ready", speed=0.5)  # blocks until the motion ends
        arm.sleep(0.5)  # hold there for 0.5 s (the control loop keeps running meanwhile)
        error = np.abs(arm.state().q - np.array(arm.config.pose("ready")))
        print(f"reached 'ready' in {motion.duration:.2f} s; largest position error {error.max() * 1e3:.2f} mrad")

        # Joint values work too: one angle per joint, rad.
        motion = arm.move_to(start, speed=0.5)
        arm.sleep(0.5)
        error = np.abs(arm.state().q - start)
        print(f"back at the start in {motion.duration:.2f} s; largest position error {error.max() * 1e3:.2f} mrad")

        arm.disable()  # damping (kp = 0) for 0.3 s, then exit motor mode
        print("disabled")
    return 0


if __name__ == "__main__":
    run(main)
