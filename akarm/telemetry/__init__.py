"""Telemetry: the per-cycle record of a run, its files and its figures.

- :mod:`akarm.telemetry.log`: :class:`~akarm.telemetry.log.TelemetryLog`, the ring buffer, CSV/NPZ.
- :mod:`akarm.telemetry.plot`: the figures of a log (matplotlib).
"""
