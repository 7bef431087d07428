"""Two arms on two CAN buses, driven as one robot by one control loop.

    .venv/bin/python examples/two_arms.py                                         # on the simulator
    .venv/bin/python examples/two_arms.py --hardware -c left=can0,right=can1     # on the real arms

robots/biarm.yaml gives each arm its own bus (`bus: left` / `bus: right`), so the two halves may
use the same CAN IDs. Every cycle the loop reads and commands both buses; a motion of all four
joints is time-synchronised across them (everyone arrives together). A mapping moves some joints
and leaves the others where they are commanded.
"""

from __future__ import annotations

import numpy as np
from _setup import open_arm, parse_args, run


def main() -> int:
    args = parse_args("Drive biarm: two arms on two buses.")
    with open_arm(args, "biarm") as (arm, _sim):
        for name, bus in arm.config.buses.items():
            joints = [f"{j.name} (id {j.can_id})" for j in arm.config.joints if j.bus == name]
            print(f"  bus {name}: {bus.interface} {bus.channel}: {', '.join(joints)}")
        arm.enable()
        print("enabled")

        arm.move_to("home", speed=0.5)  # both arms at once
        for pose in ("out", "wave", "home"):
            t0 = arm.clock.now()
            motion = arm.move_to(pose, speed=0.7)
            log = arm.telemetry(since=t0)
            # time-synchronised: every joint that moves is still moving until the very end
            moving = np.abs(log.dq_des) > 1e-3
            last = [log.t[np.nonzero(moving[:, k])[0][-1]] - t0 if moving[:, k].any() else 0.0
                    for k in range(arm.n)]
            print(f"  {pose:<5} {motion.duration:4.2f} s; moving until "
                  + ", ".join(f"{n} {t:4.2f} s" for n, t in zip(arm.names, last, strict=True)))

        # Only the right arm: a mapping {joint: rad}; the left arm keeps its commanded position.
        left_before = arm.state().q[:2].copy()
        arm.move_to({"right_shoulder": 0.8, "right_elbow": -1.0}, speed=0.7)
        arm.sleep(0.2)
        q = arm.state().q
        print(f"right arm raised to {np.round(q[2:], 3)} rad; left arm moved "
              f"{np.abs(q[:2] - left_before).max() * 1e3:.2f} mrad")
        arm.move_to("home", speed=0.5)
        arm.disable()
        print("disabled")
    return 0


if __name__ == "__main__":
    run(main)
