"""A ROS 2 participant that looks for an arm server: run by tests/system/test_ros_discovery.py in a
network namespace of its own making (``ip netns exec NS python tests/system/ros_reach.py ...``), with
Cyclone DDS configured by the environment's ``CYCLONEDDS_URI`` as rmw_cyclonedds_cpp configures a
ROS 2 node of some discovery range.

It listens to ``joint_states`` and, once it has heard some, calls ``akarm/enable``, for ``--seconds``
at most (it ends once both are done); then prints one JSON line: ``joint_states`` (how many heard),
``first`` (seconds to the first one, or null) and ``enable`` (the service's ``success``, or null:
never called, no service found).
"""

from __future__ import annotations

import argparse
import json
import time


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--domain", type=int, required=True)
    parser.add_argument("--namespace", required=True)
    parser.add_argument("--seconds", type=float, default=5.0)
    args = parser.parse_args()

    from akarm.errors import AkarmError
    from akarm.ros import msgs
    from akarm.ros.dds import Node, TriggerClient

    node = Node(args.domain, args.namespace)
    states = node.subscription("joint_states", msgs.JointState, depth=100)
    enable = TriggerClient(node, "akarm/enable")
    start = time.monotonic()
    heard, first, enabled = 0, None, None
    while time.monotonic() < start + args.seconds:
        n = sum(1 for s in states.take(100) if s.sample_info.valid_data)
        if n and first is None:
            first = time.monotonic() - start
        heard += n
        if heard >= 20 and enabled is None:
            try:
                enabled = bool(enable.call(timeout=max(1.0, start + args.seconds - time.monotonic())).success)
            except AkarmError:
                enabled = False
            break
        time.sleep(0.02)
    print(json.dumps({"joint_states": heard, "first": first, "enable": enabled}), flush=True)
    node.close()


if __name__ == "__main__":
    main()
