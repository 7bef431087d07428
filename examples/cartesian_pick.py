"""Cartesian pick and place: above a point, straight down, "grip" (a payload), lift, across, place.

    .venv/bin/python examples/cartesian_pick.py                    # on the simulator (arm6)
    .venv/bin/python examples/cartesian_pick.py --hardware -c can0  # on the real arm

Poses are the tool frame's (robots/arm6.yaml: `tool_frame: tool0`) in the base frame, metres; the
tool points straight down (roll-pitch-yaw 0, π, 0). move_to_pose() solves the joint positions and
makes a joint-space move; move_linear() keeps the tool on the straight line, jerk-limited along it.
Both check the whole motion against every joint limit before anything moves.
"""

from __future__ import annotations

import math

import numpy as np
from _setup import open_arm, parse_args, run

DOWN = (0.0, math.pi, 0.0)  # roll, pitch, yaw (rad): the tool's z axis points down
PICK = (0.45, -0.15, 0.25)  # m
PLACE = (0.40, 0.20, 0.25)
CLEARANCE = 0.12  # m above the pick and place points
OBJECT = (0.4, (0.0, 0.0, 0.05))  # kg, centre of mass in the tool frame (m): 5 cm beyond the flange


def main() -> int:
    args = parse_args("Pick an object with straight-line moves, carry it, place it (arm6).")
    from akarm.dynamics.ik import make_pose
    from akarm.dynamics.model import RobotModel

    def pose(xyz, up=0.0):
        return make_pose(np.add(xyz, (0.0, 0.0, up)), rpy=DOWN)

    with open_arm(args, "arm6") as (arm, sim):
        arm.enable()
        arm.move_to("home", speed=0.5)

        def line(target, what: str, **limits) -> None:
            """A straight move; report how far the tool (at the measured joints) strayed from the line."""
            start = arm.tool_pose()[:3, 3]
            t0 = arm.clock.now()
            motion = arm.move_linear(target, **limits)
            log = arm.telemetry(since=t0)
            end = target[:3, 3]
            u = (end - start) / np.linalg.norm(end - start)
            off = max(np.linalg.norm((d := arm.tool_pose(q)[:3, 3] - start) - (d @ u) * u) for q in log.q)
            print(f"{what}: {np.linalg.norm(end - start) * 100:.0f} cm in {motion.duration:.2f} s, "
                  f"within {off * 1e3:.2f} mm of the line")

        arm.move_to_pose(pose(PICK, CLEARANCE), speed=0.5)  # joint space: the IK solution nearest 'home'
        print(f"above the object at {np.round(arm.tool_pose()[:3, 3], 3).tolist()} m, tool down")
        line(pose(PICK), "descend", max_velocity=0.1)  # at most 10 cm/s

        # "Grip": tell the arm what it now carries, as the gripper closes. The feed-forward carries
        # the object and the collision reflex expects its weight: unannounced, that weight would be an
        # external torque, and more than the elbow's threshold. (In the simulator the object becomes real.)
        arm.set_payload(*OBJECT)
        if sim is not None:
            sim.set_payload(*OBJECT)
        arm.sleep(0.3)
        model = RobotModel(arm.config)  # a model of our own, to compute the object's weight on the joints
        empty = model.gravity(arm.state().q)
        model.set_payload(*OBJECT)
        weight = np.abs(model.gravity(arm.state().q) - empty)
        limit = np.array([math.inf if x is None else x for x in arm.collision_thresholds.values()])
        k = int(np.argmax(weight / limit))
        print(f"gripped {OBJECT[0]:g} kg: its weight on the {arm.names[k]} is {weight[k]:.2f} N·m (collision threshold "
              f"{limit[k]:.2f}); external torque estimate at most {np.abs(arm.state().tau_ext).max():.2f} N·m")

        line(pose(PICK, CLEARANCE), "lift")
        line(pose(PLACE, CLEARANCE), "carry")
        line(pose(PLACE), "lower", max_velocity=0.1)
        if sim is not None:
            sim.clear_payload()
        arm.clear_payload()
        line(pose(PLACE, CLEARANCE), "retreat")
        arm.move_to("home", speed=0.5)
        arm.disable()
        print("disabled")
    return 0


if __name__ == "__main__":
    run(main)
