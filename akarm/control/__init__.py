"""The real-time side: the controller, its joints, its loop and its supervision.

- :mod:`akarm.control.controller`: :class:`~akarm.control.controller.Controller`, the buses, the
  mode machine and the cycle; the one way out.
- :mod:`akarm.control.joints`: one ``Joint`` interface for MIT and servo motors; the reply router.
- :mod:`akarm.control.loop`: the fixed-rate loop and its statistics.
- :mod:`akarm.control.modes`: the mode enum and its transition table.
- :mod:`akarm.control.safety`: the supervisor (every check, no bus needed).
- :mod:`akarm.control.feedforward`: the feed-forward torque.
- :mod:`akarm.control.collision`: the generalized-momentum observer and the collision reflex.
- :mod:`akarm.control.probe`: reading motors without enabling them (status, scan, zero).
"""
