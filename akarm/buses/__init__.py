"""CAN buses: opening python-can buses, building frames fast, the ``akarm_local`` interface, and
which process owns which bus.

- :mod:`akarm.buses.bus`: :func:`~akarm.buses.bus.open_bus`, errors translated per cause.
- :mod:`akarm.buses.frames`: fast ``can.Message`` building for the hot path.
- :mod:`akarm.buses.localbus`: the ``akarm_local`` python-can interface (shared memory).
- :mod:`akarm.buses.ownership`: one ``flock``ed file per bus, so two controllers are refused.
"""
