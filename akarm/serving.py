"""``akarm.ArmServer`` and ``akarm.serve``: the arm server with its ROS 2 node, put together.

::

    import akarm
    arm = akarm.Arm.from_yaml("robots/arm6.yaml")
    with arm:
        akarm.serve(arm, namespace="arm6")     # enables without a kick, holds, serves until Ctrl-C/SIGTERM
    # leaving: damped, then disabled

:class:`ArmServer` is :class:`~akarm.server.server.ArmServerCore` (the buses claimed, the arm held,
the CLI's socket) with, unless ``ros=False``, the ROS 2 node of :mod:`akarm.ros.node` as its
frontend: ``joint_states``, ``joint_trajectory``, ``akarm/status``, the
``akarm/enable|disable|hold`` services and MoveIt's ``CONTROLLER/follow_joint_trajectory`` action
over Cyclone DDS (the ``ros`` extra), seen by every ROS 2 node on this machine (ROS 2's ``LOCALHOST``)
unless closed to the loopback interface (``ros_loopback``) or opened (``ros_network``, ROS 2's
environment variables). This module sits above both layers, so the server
knows nothing of ROS and ROS only the server's commands.

Stopping it (:meth:`ArmServer.stop`, SIGINT or SIGTERM in :func:`serve`) damps and disables the arm.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

from akarm.errors import ArgumentError
from akarm.server.server import ArmServerCore, Frontend

if TYPE_CHECKING:
    from akarm.arm import Arm

__all__ = ["ArmServer", "serve"]


def _default_domain() -> int:
    try:
        return int(os.environ.get("ROS_DOMAIN_ID", "0"))
    except ValueError:
        return 0


class ArmServer(ArmServerCore):
    """Serves ``arm`` to the CLI (local socket) and to ROS 2 (DDS) until :meth:`stop`.

    Args:
        arm: the arm; opened here if it is not open yet (and then closed by :meth:`stop`). It must
            run on the wall clock (a lock-step simulation has nobody to advance its time).
        domain: DDS domain ID (default: ``ROS_DOMAIN_ID``, else 0).
        namespace: ROS 2 namespace of every topic and service (default none).
        ros: offer the ROS 2 interfaces (needs the ``ros`` extra); False serves the CLI only.
        joint_states_hz: rate of ``joint_states``; default the loop rate divided by
            ``round(rate_hz / 100)`` (100 Hz at 500 Hz).
        status_hz: rate of ``akarm/status``.
        enable: enable (without a kick) and hold when starting.
        log: where the server's one-line reports go (default: stderr).
        ros_network: let the ROS 2 node talk to other machines (ROS 2's ``SUBNET`` discovery range).
            By default it is a node at ROS 2's ``LOCALHOST`` range, as rmw_cyclonedds_cpp configures
            one: every ROS 2 node on this machine sees it, whatever its range, and another machine only
            if it names this one in its static peers; unless ``ROS_AUTOMATIC_DISCOVERY_RANGE``,
            ``ROS_STATIC_PEERS``, ``ROS_LOCALHOST_ONLY`` or a ``CYCLONEDDS_URI`` of the user's own say
            otherwise (:func:`akarm.ros.dds.discovery`).
        ros_loopback: keep the ROS 2 node on the loopback interface alone, whatever the environment
            says: no other machine reaches it, even by name, and on this machine only participants that
            look for it on the loopback interface (``akarm.ros.dds.LOOPBACK_CONFIG``, ROS 2's
            ``LOCALHOST``).
        controller: the FollowJointTrajectory action is ``NS/CONTROLLER/follow_joint_trajectory``
            (MoveIt's ``moveit_controllers.yaml`` names it: ``akarm ros-config``).
        ros_distro: the ROS 2 distribution whose message layouts to speak: ``humble``, ``jazzy``
            (the same as humble's but for ``ros_discovery_info``) or ``rolling`` (the action's
            feedback has ``index`` and ``multi_dof_index``).
        node_name: the ROS 2 node's name (``ros2 node list`` shows ``/NS/NODE``).

    A missing ``ros`` extra, a DDS that cannot start, a bad namespace, controller or node name, or
    an unknown distribution is raised by :meth:`start` before anything is opened or enabled.
    """

    def __init__(self, arm: Arm, *, domain: int | None = None, namespace: str = "", ros: bool = True,
                 joint_states_hz: float | None = None, status_hz: float = 2.0, enable: bool = True,
                 log: Callable[[str], None] | None = None, ros_network: bool = False, ros_loopback: bool = False,
                 controller: str = "arm_controller", ros_distro: str = "jazzy", node_name: str = "akarm") -> None:
        for what, hz in (("joint_states_hz", joint_states_hz), ("status_hz", status_hz)):
            if hz is not None and not (isinstance(hz, int | float) and 0 < hz < math.inf):
                raise ArgumentError(f"{what} must be a positive number of Hz, got {hz!r}",
                                    fix="e.g. --joint-states-hz 100 --status-hz 2")
        self.domain = _default_domain() if domain is None else int(domain)
        self.namespace = namespace.strip("/")
        self.ros = ros
        rate = arm.config.rate_hz
        self.joint_states_hz = joint_states_hz if joint_states_hz is not None else rate / max(1, round(rate / 100.0))
        self.status_hz = status_hz
        if ros_network and ros_loopback:
            raise ArgumentError("ros_network and ros_loopback contradict each other (--ros-network, --ros-loopback)",
                                fix="give one of them (neither: every ROS 2 node on this machine, as ROS 2's "
                                    "LOCALHOST)")
        self.ros_network, self.ros_loopback = ros_network, ros_loopback
        self.controller, self.ros_distro, self.node_name = controller, ros_distro, node_name
        super().__init__(arm, frontends=[self._ros_node] if ros else [], enable=enable, log=log,
                         about={"domain": self.domain, "namespace": self.namespace})

    def _ros_node(self, server: ArmServerCore) -> Frontend:
        from akarm.ros.dds import discovery  # akarm.ros says so (AkarmError) when Cyclone DDS is not installed
        from akarm.ros.node import RosNode

        return RosNode(server, self.domain, self.namespace, self.joint_states_hz, self.status_hz,
                       discovery(network=self.ros_network, loopback=self.ros_loopback), controller=self.controller,
                       distro=self.ros_distro, node_name=self.node_name)


def serve(arm: Arm, **options: Any) -> None:
    """Serve ``arm`` (see :class:`ArmServer` for ``options``) until SIGINT or SIGTERM, then damp and
    disable it. Blocks; for a script that owns its Arm."""
    with ArmServer(arm, **options) as server:
        server.wait()
