"""A gripper's fingers as the URDF moves them: the robot file's ``gripper.fingers`` are URDF joints
that the reduced model (:class:`akarm.dynamics.model.RobotModel`) holds at 0; whatever draws the jaws at
the width measured (:mod:`akarm.view`, the simulated camera :mod:`akarm.sim.camera`) slides each finger
link by :func:`finger_slides` times its joint's position (half the width each, as ``joint_states``
has them)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from akarm.dynamics.model import RobotModel

__all__ = ["finger_slides"]


def finger_slides(model: RobotModel) -> dict[str, np.ndarray]:
    """Per URDF link that one of the gripper's finger joints moves (a prismatic joint of the robot
    file's ``gripper.fingers``): the direction it slides, in the frame of the body it rides on in the
    reduced model, per metre of that joint (m/m). Empty without a gripper or fingers."""
    g = model.config.gripper
    if g is None or not g.fingers:
        return {}
    full = pin.buildModelFromUrdf(str(model.config.urdf))
    data = full.createData()
    slides: dict[str, np.ndarray] = {}
    for finger in g.fingers:
        if not full.existJointName(finger):
            continue
        fj = full.getJointId(finger)
        if full.nqs[fj] != 1 or full.nvs[fj] != 1:
            continue
        q = pin.neutral(full)
        pin.forwardKinematics(full, data, q)
        parent = int(full.parents[fj])
        at_zero = (data.oMi[parent].inverse() * data.oMi[fj]).translation.copy()
        q[full.idx_qs[fj]] += 0.01
        pin.forwardKinematics(full, data, q)
        slide = ((data.oMi[parent].inverse() * data.oMi[fj]).translation - at_zero) / 0.01
        if np.linalg.norm(slide) < 0.5:  # not a slide (a revolute finger): drawn where it is locked
            continue
        for f in full.frames:
            if int(f.parentJoint) == fj and f.type == pin.FrameType.BODY:
                slides[str(f.name)] = np.asarray(slide, dtype=float)
    return slides
