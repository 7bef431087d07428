"""Pick and place with the gripper: open, go down to the object, close on it, carry it, put it down.

    .venv/bin/python examples/pick_and_place.py                    # on the simulator (arm6g)
    .venv/bin/python examples/pick_and_place.py --hardware -c can0  # on the real arm

robots/arm6g.yaml is arm6 with a parallel gripper (docs/gripper.md). The simulator gets a 30 mm
object at the pick point; the jaws close on it force-limited (20 N) and hold it while the arm
carries it, and the arm is told of its weight while it is held (set_payload), so that the
feed-forward carries it and the collision reflex does not take it for a push. On the simulator the
example ends by saying where the object is now.
"""

from __future__ import annotations

import math

import numpy as np
from _setup import open_arm, parse_args, run

DOWN = (0.0, math.pi, 0.0)  # roll, pitch, yaw (rad): the tool's z axis points down
PICK = (0.45, -0.15, 0.20)  # m: where the object is (its centre, between the fingertips at tool0)
PLACE = (0.40, 0.20, 0.20)
CLEARANCE = 0.10  # m above the pick and place points
WIDTH = 0.03  # m: the object's width
MASS = 0.3  # kg
FORCE = 20.0  # N: how hard the jaws hold it


def main() -> int:
    args = parse_args("Pick an object with the gripper, carry it, place it (arm6g).")
    from akarm.dynamics.ik import make_pose

    def pose(xyz, up=0.0):
        return make_pose(np.add(xyz, (0.0, 0.0, up)), rpy=DOWN)

    with open_arm(args, "arm6g") as (arm, sim):
        gripper = arm.gripper
        assert gripper is not None
        if sim is not None:
            sim.place_object(WIDTH, mass=MASS, position=PICK)
        arm.enable()
        arm.move_to("home", speed=0.5)
        s = gripper.open()
        print(f"gripper open: {s.width * 1e3:.1f} mm")
        arm.move_to_pose(pose(PICK, CLEARANCE), speed=0.5)
        arm.move_linear(pose(PICK), max_velocity=0.1)
        s = gripper.close(force=FORCE)
        if not s.grasped:
            print(f"nothing between the jaws: closed to {s.width * 1e3:.1f} mm")
            return 1
        arm.set_payload(MASS)  # held: the arm carries it from now on
        print(f"grasped at {s.width * 1e3:.1f} mm, squeezing {s.force:.1f} N (asked {FORCE:g} N)"
              + (f"; the simulator counts {sim.object_force():.1f} N" if sim is not None else ""))
        arm.move_linear(pose(PICK, CLEARANCE))
        arm.move_linear(pose(PLACE, CLEARANCE))
        arm.move_linear(pose(PLACE), max_velocity=0.1)
        s = gripper.state()
        print(f"carried it: still grasped {s.grasped}, squeezing {s.force:.1f} N, motor {s.temperature:.1f} °C")
        gripper.open(wait=False)  # let go...
        arm.clear_payload()  # ...and the arm no longer carries it
        s = gripper.wait()
        print(f"released: {s.width * 1e3:.1f} mm open")
        arm.move_linear(pose(PLACE, CLEARANCE))
        arm.move_to("home", speed=0.5)
        if sim is not None:
            where = sim.object_position()
            assert where is not None
            moved = np.linalg.norm(where - np.array(PICK))
            off = np.linalg.norm(where - np.array(PLACE))
            print(f"object at {np.round(where, 3).tolist()} m: moved {moved * 100:.1f} cm, {off * 1e3:.1f} mm from "
                  "the place point")
        arm.disable()
        print("disabled")
    return 0


if __name__ == "__main__":
    run(main)
