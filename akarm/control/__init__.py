"""The real-time side: the controller, its parts, its joints, its loop and its supervision.

- :mod:`akarm.control.controller`: :class:`~akarm.control.controller.Controller`, the mode machine
  and the cycle, composing the parts below.
- :mod:`akarm.control.options`: :class:`~akarm.control.options.ControllerOptions`, what it is built from.
- :mod:`akarm.control.busset`: the buses as one set (open, drain and route, send, a lost bus).
- :mod:`akarm.control.enabler`: enabling without a kick (listen, contact, settle, ramp).
- :mod:`akarm.control.motions`: the plan followed and its ``Motion``, or the pose held; the path recorder.
- :mod:`akarm.control.exits`: the one way out (close, atexit, finalizer, signals).
- :mod:`akarm.control.view`: read-only observability (``arm.observe``).
- :mod:`akarm.control.joints`: one ``Joint`` interface for MIT and servo motors; the reply router.
- :mod:`akarm.control.loop`: the fixed-rate loop and its statistics.
- :mod:`akarm.control.cpuidle`: keeping the CPUs out of deep idle states while the loop runs.
- :mod:`akarm.control.modes`: the mode enum and its transition table.
- :mod:`akarm.control.safety`: the supervisor (every check, no bus needed).
- :mod:`akarm.control.feedforward`: the feed-forward torque.
- :mod:`akarm.control.collision`: the generalized-momentum observer and the collision reflex.
- :mod:`akarm.control.probe`: reading motors without enabling them (status, scan, zero).
"""
