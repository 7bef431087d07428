"""ROS 2 interfaces over Cyclone DDS, without a ROS installation (the ``ros`` extra: ``pip install -e ".[ros]"``).

- :mod:`akarm.ros.msgs`: the ROS 2 messages akarm uses, as DDS types with ROS 2's type names.
- :mod:`akarm.ros.dds`: ROS 2 naming (``rt/``, ``rq/``, ``rr/``), QoS, ``std_srvs/Trigger`` services
  laid out as rmw_cyclonedds_cpp lays them out.
- :mod:`akarm.ros.node`: the ROS 2 face of an arm server (``joint_states``, ``joint_trajectory``,
  ``akarm/status``, ``akarm/enable|disable|hold``); :class:`akarm.ArmServer` puts the two together.

See ``docs/ros2.md``.
"""

from akarm.errors import AkarmError

try:
    import cyclonedds  # noqa: F401
except ImportError as e:  # pragma: no cover - depends on the install
    raise AkarmError("ROS 2 interfaces need Cyclone DDS's Python binding, which is not installed",
                     fix='pip install -e ".[ros]" (or pip install cyclonedds), or serve without ROS: --no-ros') from e
