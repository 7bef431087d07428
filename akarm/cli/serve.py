"""``akarm serve ROBOT.yaml``: enable the arm, hold it, and serve it to the CLI and to ROS 2 until stopped.

::

    akarm serve robots/arm6.yaml                            # ROS 2 domain $ROS_DOMAIN_ID (or 0), no namespace
    akarm serve robots/arm6.yaml --namespace left --domain 7
    akarm move robots/arm6.yaml ready                       # another terminal: moves through the server

While it runs, ``move``, ``enable``, ``disable``, ``status``, ``teach`` and ``replay`` for this robot
use it (the arm stays held between them), a second controller on its buses is refused, and ROS 2
sees ``NS/joint_states``, ``NS/joint_trajectory``, ``NS/akarm/status``, the
``NS/akarm/enable|disable|hold`` services and the FollowJointTrajectory action
``NS/CONTROLLER/follow_joint_trajectory`` that MoveIt drives (``docs/ros2.md``; ``akarm ros-config``
writes MoveIt's side): by every ROS 2 node on this machine, whatever its discovery range (the node
is at ROS 2's LOCALHOST range; another machine reaches it only by naming this one in its
``ROS_STATIC_PEERS``), unless ``--ros-loopback`` closes it to the loopback interface or
``--ros-network`` (or ROS 2's ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET``, ``ROS_STATIC_PEERS``, a
``CYCLONEDDS_URI`` of your own) opens it to the network. A safety stop latches: nothing moves
until ``akarm enable`` (or the ``akarm/enable`` service) acknowledges it. Ctrl-C or SIGTERM: the
arm is damped, then disabled, and the exit status is 0.
"""

from __future__ import annotations

import argparse
import signal
import sys
from typing import TYPE_CHECKING

from akarm.cli.common import add_profile_argument, add_robot_arguments, load_from_args, loop_options

if TYPE_CHECKING:
    from akarm.serving import ArmServer


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """The verb's arguments."""
    from akarm.cli.options import duration

    add_robot_arguments(parser)
    parser.add_argument("--domain", type=int, metavar="N", help="DDS domain ID (default: $ROS_DOMAIN_ID, else 0)")
    parser.add_argument("--namespace", default="", metavar="NS", help="ROS 2 namespace of the topics and services")
    parser.add_argument("--controller", default="arm_controller", metavar="NAME",
                        help="the FollowJointTrajectory action is NS/NAME/follow_joint_trajectory "
                             "(default: arm_controller; akarm ros-config writes MoveIt's side)")
    parser.add_argument("--ros-distro", default="jazzy", choices=("humble", "jazzy", "rolling"),
                        help="the ROS 2 message layouts to speak (default: jazzy; rolling's action feedback "
                             "has two more fields, humble's ros_discovery_info longer IDs)")
    parser.add_argument("--joint-states-hz", type=float, metavar="HZ",
                        help="joint_states rate (default: the loop rate divided by round(rate/100), ~100 Hz)")
    parser.add_argument("--feedback-timeout", type=duration, metavar="S",
                        help="watchdog: stop the arm when a joint's feedback is older (default: the profile's, 0.02 "
                             "normally; a joint's own feedback_timeout in the YAML wins)")
    add_profile_argument(parser)
    parser.add_argument("--no-ros", action="store_true",
                        help="serve the local CLI only (no DDS; for machines without the ros extra)")
    parser.add_argument("--ros-network", action="store_true",
                        help="let ROS 2 participants on other machines see and command the arm (ROS 2's SUBNET "
                             "discovery range; default: ROS 2's LOCALHOST: every ROS 2 node on this machine, other "
                             "machines only by naming this one in ROS_STATIC_PEERS, unless "
                             "ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_STATIC_PEERS or CYCLONEDDS_URI say otherwise)")
    parser.add_argument("--ros-loopback", action="store_true",
                        help="keep ROS 2 on the loopback interface alone, whatever the environment says: no other "
                             "machine reaches the arm, even by name, and on this machine only participants that "
                             "look for it on the loopback interface (ROS 2 nodes at ROS_AUTOMATIC_DISCOVERY_RANGE="
                             "LOCALHOST, or CYCLONEDDS_URI set to akarm.ros.dds.LOOPBACK_CONFIG)")

    from akarm.cli.view import add_view_options

    add_view_options(parser)


def action(server: ArmServer) -> str:
    """The FollowJointTrajectory action's full name and layout, as the start line says it."""
    from akarm.ros.action import action_name
    from akarm.ros.dds import ros_name

    return f"{ros_name(server.namespace, action_name(server.controller))} ({server.ros_distro})"


def run(args: argparse.Namespace) -> int:
    """Serve until SIGINT/SIGTERM; then damp and disable the arm; exit 0."""
    from akarm.arm import Arm
    from akarm.cli.common import format_q
    from akarm.serving import ArmServer

    if args.ros_network and args.ros_loopback:
        from akarm.errors import ArgumentError

        raise ArgumentError("--ros-network and --ros-loopback contradict each other",
                            fix="give one of them (neither: every ROS 2 node on this machine, as ROS 2's LOCALHOST)")
    config = load_from_args(args)
    arm = Arm(config, feedback_timeout=args.feedback_timeout, **loop_options(args))
    for flag, given in (("--ros-network", args.ros_network), ("--ros-loopback", args.ros_loopback)):
        if args.no_ros and given:
            from akarm.errors import ArgumentError

            raise ArgumentError(f"{flag} and --no-ros contradict each other", fix="give one of them")
    server = ArmServer(arm, domain=args.domain, namespace=args.namespace, ros=not args.no_ros,
                       joint_states_hz=args.joint_states_hz, ros_network=args.ros_network,
                       ros_loopback=args.ros_loopback, controller=args.controller, ros_distro=args.ros_distro)
    view = None
    if args.view:  # made first: a missing view extra is said before anything is enabled
        from akarm.cli.view import make_view_process
        from akarm.view.sources import ServerSource

        view = make_view_process(args, config, ServerSource(server))
    # from here on a signal only asks the server to stop: it cannot cut enabling or disabling short
    previous = {s: signal.signal(s, lambda signum, frame: server.request_stop()) for s in (signal.SIGINT,
                                                                                           signal.SIGTERM)}
    try:
        server.start()
        if view is not None:
            from akarm.cli.view import show_view

            show_view(view)
        ros = "ROS 2 off (--no-ros)" if args.no_ros else \
            f"ROS 2 domain {server.domain}, namespace '/{server.namespace}', action {action(server)}"
        print(f"serving {config.name}: holding at {format_q(server.arm.state().q)}; {ros}; "
              "Ctrl-C or SIGTERM stops (damped, then disabled)", flush=True)
        server.wait(signals=False)
        print("stopping: damping, then disabling", file=sys.stderr, flush=True)
    finally:
        if view is not None:  # first: nobody presses a button of a server that is stopping
            view.stop()
        server.stop()
        for s, handler in previous.items():
            signal.signal(s, handler)
    print("disabled", flush=True)
    return 0
