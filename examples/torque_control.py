"""Torque control: switch the position loop off and run your own control law at 100 Hz.

    .venv/bin/python examples/torque_control.py                    # on the simulator (arm6)
    .venv/bin/python examples/torque_control.py --hardware -c can0  # on the real arm

An MIT-mode command carries a position, a velocity, gains kp and kd, and a torque; the motor
applies ``kp·(q_des - q) + kd·(dq_des - dq) + torque``. With ``set_gains(kp=0, kd=small)`` only the
damping is left, the Arm keeps adding its feed-forward (the arm's weight, so it floats), and
``set_extra_torque(tau)`` adds your own torque (N·m per joint) to every command. Here the law is a
soft virtual spring around the `ready` pose (10 N·m/rad, a ninth of the elbow's kp): the elbow is
given a 3 N·m nudge for 0.3 s, swings out, and the spring brings it back.

The Arm's feed-forward is the arm's weight at the *commanded* pose (still `ready`). Pushed away
from it, the weight changes; the law adds the difference, ``g(q) - g(ready)``, from its own
:class:`akarm.dynamics.model.RobotModel` (the Arm's own model belongs to its control loop's thread).
"""

from __future__ import annotations

import numpy as np
from _setup import open_arm, parse_args, run

from akarm.dynamics.model import RobotModel

STIFFNESS = 10.0  # N·m/rad, every joint
DAMPING = 0.5  # N·m·s/rad: the motors' own kd (runs in the drive, at its loop rate)
NUDGE = 3.0  # N·m on the elbow
RATE = 100.0  # Hz: this script's control law


def main() -> int:
    args = parse_args("MIT torque control on arm6: a virtual spring, gravity carried.")
    with open_arm(args, "arm6") as (arm, _sim):
        arm.enable()
        arm.move_to("ready", speed=0.5)
        ready = np.array(arm.config.pose("ready"))
        elbow = arm.names.index("elbow")
        model = RobotModel(arm.config)  # gravity g(q), N·m, for the law below
        g_ready = model.gravity(ready)

        arm.set_gains(kp=0.0, kd=DAMPING)  # no position loop in the drives from here on
        print(f"torque control: kp = 0, kd = {DAMPING} N·m·s/rad, virtual spring {STIFFNESS} N·m/rad at "
              f"{RATE:g} Hz; nudging the elbow with {NUDGE} N·m for 0.3 s")
        if args.hardware:
            print("(you may also push the arm by hand: it gives way softly, and comes back)")
        peak = 0.0
        t_start = arm.clock.now()
        for _ in range(int(3.0 * RATE)):  # 3 s
            t = arm.clock.now() - t_start
            q = arm.state().q
            tau = -STIFFNESS * (q - ready)  # the control law: a spring pulling towards `ready`,
            tau += model.gravity(q) - g_ready  # with the weight carried wherever the arm is
            if t < 0.3:
                tau[elbow] += NUDGE
            arm.set_extra_torque(tau)  # added to the feed-forward in every 500 Hz command
            peak = max(peak, abs(q[elbow] - ready[elbow]))
            arm.sleep(1.0 / RATE)
        arm.set_extra_torque(None)
        offset = abs(arm.state().q[elbow] - ready[elbow])
        friction = arm.config.joints[elbow].friction_model().coulomb
        print(f"the elbow swung out {peak * 1e3:.0f} mrad (about {NUDGE / STIFFNESS * 1e3:.0f} expected from a "
              f"{STIFFNESS:g} N·m/rad spring) and came back to {offset * 1e3:.0f} mrad from `ready` "
              f"(a soft spring stops where static friction holds: up to {friction / STIFFNESS * 1e3:.0f} mrad)")

        # Back to position control. The commanded position is still `ready` and the arm stands a
        # little off it: raise the gains over 0.5 s rather than at once, so the pull-in is gentle.
        kp = np.array([j.gains.kp for j in arm.config.joints])
        kd = np.array([j.gains.kd for j in arm.config.joints])
        for s in np.linspace(0.0, 1.0, int(0.5 * RATE)):
            arm.set_gains(kp=s * kp, kd=DAMPING + s * (kd - DAMPING))
            arm.sleep(1.0 / RATE)
        arm.sleep(0.3)
        print(f"position control again: {abs(arm.state().q[elbow] - ready[elbow]) * 1e3:.1f} mrad from `ready`")
        arm.move_to("home", speed=0.5)
        print("moved to 'home'")
        arm.disable()
        print("disabled")
    return 0


if __name__ == "__main__":
    run(main)
