"""Testing programs against a simulated arm.

- :mod:`akarm.testing.rig`: :class:`~akarm.testing.rig.SimulatedArm`, a simulated arm for tests,
  in lock step in this process or in a simulator process of its own.
- :mod:`akarm.testing.plugin`: the pytest plugin (registered as the ``pytest11`` entry point
  ``akarm``): fixtures giving a test a ``SimulatedArm``.
"""
