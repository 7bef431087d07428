"""A ROS 2 participant that tries to reach an arm server: run by tests/system/test_serve_network.py
inside a network namespace (``ip netns exec NS python tests/system/ros_peer.py ...``).

It looks for the server's ``joint_trajectory`` reader, listens to ``joint_states``, publishes a
trajectory moving one joint, and calls ``akarm/hold``, for ``--seconds`` at most (it ends once it has
called ``akarm/hold`` and heard 50 ``joint_states``); then prints one JSON line:
what it saw and did. Cyclone DDS's configuration is the environment's (``CYCLONEDDS_URI``).
"""

from __future__ import annotations

import argparse
import json
import time


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--domain", type=int, required=True)
    parser.add_argument("--namespace", required=True)
    parser.add_argument("--joint", required=True)
    parser.add_argument("--position", type=float, required=True)
    parser.add_argument("--seconds", type=float, default=8.0)
    args = parser.parse_args()

    from akarm.errors import AkarmError
    from akarm.ros import msgs
    from akarm.ros.dds import Node, TriggerClient

    node = Node(args.domain, args.namespace)
    states = node.subscription("joint_states", msgs.JointState, depth=100)
    trajectory = node.publisher("joint_trajectory", msgs.JointTrajectory)
    hold = TriggerClient(node, "akarm/hold")
    heard, sent, matched, held = 0, 0, False, None
    end = time.monotonic() + args.seconds
    sent_at = 0.0
    while time.monotonic() < end:
        heard += sum(1 for _ in states.take(100))
        if trajectory.get_matched_subscriptions():
            if not matched:
                matched = True
                trajectory.write(msgs.JointTrajectory(joint_names=[args.joint], points=[
                    msgs.JointTrajectoryPoint(positions=[args.position], time_from_start=msgs.Duration(1, 0))]))
                sent += 1
                sent_at = time.monotonic()
            if held is None and hold.ready() and time.monotonic() > sent_at + 2.5:  # once it has arrived
                try:
                    held = bool(hold.call(timeout=3.0).success)
                except AkarmError:
                    held = False
            if held is not None and heard > 50:
                break  # done: the sooner it ends, the less a loaded machine can stop the arm meanwhile
        time.sleep(0.05)
    print(json.dumps({"matched": matched, "joint_states": heard, "sent": sent, "held": held}), flush=True)
    node.close()


if __name__ == "__main__":
    main()
