"""Rigid-body dynamics of the arm (Pinocchio): the model, gravity over the ranges, inverse kinematics.

- :mod:`akarm.dynamics.model`: :class:`~akarm.dynamics.model.RobotModel` (gravity, RNEA, ABA, FK,
  Jacobians, payload) in the config's joint order.
- :mod:`akarm.dynamics.gravity`: the largest gravity torque per joint over the joint ranges.
- :mod:`akarm.dynamics.ik`: tool poses and damped-least-squares inverse kinematics.
"""
