"""Latency of the FollowJointTrajectory action of `akarm serve`, as MoveIt would see it.

    .venv/bin/python benchmarks/bench_action.py [--goals 30] [--distro jazzy] [--robot robots/arm6.yaml]

Three processes, as on a robot: the simulated drivers (`akarm sim`, akarm_local bus), `akarm serve`,
and this one: the action client of the system tests (tests/system/action_client.py: rosbags'
codecs, rcl's readiness rule), and a listener on the CAN bus. Times are wall-clock (`time.time()`):
a frame's is when its sender wrote it to the bus, a reply's or a feedback message's when this
process woke up with it.

- send_goal → first command frame: the goal is sent (a move of one joint from rest); the first
  command frame of the new motion is found as benchmarks/bench_serve_latency.py finds it (the
  feed-forward torque leaves its holding value).
- motion end → result: the motion ends with the first command frame at the goal's final position
  (the plan's end; it then holds there); the result arrives once the server has seen the arm within
  the goal tolerance there (velocity under 0.05 rad/s by default): so this includes the arm settling.
- feedback: messages per second while each goal runs, and the gaps between them.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import time
import uuid
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_serve_latency import Frames, command_onsets, percentiles  # noqa: E402

from akarm.protocol import mit  # noqa: E402
from akarm.robotfile.load import load_robot  # noqa: E402
from akarm.ros import dds  # noqa: E402
from akarm.ros.action import action_name  # noqa: E402
from akarm.sim.process import SimulatorProcess  # noqa: E402
from tests.system.action_client import ActionClient  # noqa: E402


def enable_again(client: ActionClient, tries: int = 5) -> bool:
    """Acknowledge a stop of the loaded machine; an enable may itself be stopped by the next stall."""
    enable = dds.TriggerClient(client.node, "akarm/enable")
    for _ in range(tries):
        if enable.call(timeout=30).success:
            return True
        time.sleep(1.0)
    return False


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robot", default=str(ROOT / "robots" / "arm6.yaml"))
    ap.add_argument("--goals", type=int, default=30, help="goals to time")
    ap.add_argument("--distro", default="jazzy", choices=("humble", "jazzy", "rolling"))
    ap.add_argument("--joint", type=int, default=1, help="the joint the goals move (default 1, arm6's shoulder_lift)")
    ap.add_argument("--between", type=float, nargs=2, default=(0.2, 0.6), metavar=("A", "B"),
                    help="the goals go back and forth between these positions, rad")
    ap.add_argument("--duration", type=float, default=0.8, help="each goal's time_from_start, s")
    args = ap.parse_args()
    os.environ["CYCLONEDDS_URI"] = dds.LOOPBACK_CONFIG
    channel, ns, domain = f"bench-action-{os.getpid()}", f"bench{os.getpid()}", 100 + os.getpid() % 100
    config = load_robot(args.robot)
    jt = config.joints[args.joint]
    names = list(config.joint_names)
    load0 = os.getloadavg()
    with SimulatorProcess(args.robot, channel=channel):
        serve = subprocess.Popen([sys.executable, "-m", "akarm", "serve", args.robot, "-i", "akarm_local", "-c",
                                  channel, "--domain", str(domain), "--namespace", ns, "--ros-distro", args.distro,
                                  "--feedback-timeout", "0.5"],  # a stall of the shared machine must not stop it
                                 stdout=subprocess.PIPE, text=True)
        try:
            assert serve.stdout is not None and serve.stdout.readline().startswith("serving"), "serve did not start"
            client = ActionClient(domain, ns, action_name("arm_controller"), args.distro)
            client.wait_ready()
            frames = Frames(channel)
            time.sleep(1.0)
            # sent, reply received, result received, goal id, target
            runs: list[tuple[float, float, float, bytes, float]] = []
            failed: list[str] = []
            for k in range(args.goals):
                target = args.between[k % 2]
                time.sleep(0.25 + 0.05 * np.random.rand())  # at rest, holding; a random phase to the loop
                gid = uuid.uuid4().bytes
                goal = client.goal([names[args.joint]], [(args.duration, [target])])
                sent, replied, reply = client.send(gid, goal)
                assert reply.accepted
                received, res = client.result(gid)
                if res.status != 4:  # a stop of the loaded machine: said, acknowledged, not timed
                    failed.append(res.result.error_string)
                    print(f"goal {k} did not succeed: {res.result.error_string}", file=sys.stderr)
                    if not enable_again(client):
                        print("the arm could not be enabled again: the figures below are from the goals before",
                              file=sys.stderr)
                        break
                    # untimed: on to this goal's target, where the next goal sets out from (so that it moves)
                    again = uuid.uuid4().bytes
                    client.send(again, client.goal([names[args.joint]], [(args.duration, [target])]))
                    client.result(again)
                    continue
                runs.append((sent, replied, received, gid, target))
            time.sleep(0.2)
            frames.close()
            feedback = {r[3]: client.feedback_of(r[3]) for r in runs}
            client.close()
        finally:
            serve.terminate()
            serve.wait(30)
    load1 = os.getloadavg()

    if failed:
        print(f"{len(failed)} of {args.goals} goals did not succeed (left out of the figures below)")
    onsets, threshold, commanded = command_onsets(frames.frames, jt, [r[0] for r in runs])
    # the motion's end: the first command at the goal's final position after which the commands stay there
    cmds = [(m.timestamp, mit.decode_command(jt.motor, bytes(m.data))) for m in frames.frames
            if m.arbitration_id == jt.can_id and not m.is_extended_id and mit.special_frame(bytes(m.data)) is None]
    t = np.array([c[0] for c in cmds])
    q = np.array([c[1].position for c in cmds])
    to_result, settle = [], []
    for sent, _, received, _, target in runs:
        sel = np.nonzero((t > sent) & (t < received + 0.2))[0]
        at_end = sel[np.abs(q[sel] - target) < 1e-3]  # within the command's position step (0.4 mrad) and a bit
        if len(at_end):
            to_result.append(received - t[at_end[0]])
            settle.append(t[at_end[0]] - sent)
    rates, gaps = [], []
    for *_, gid, _ in runs:
        ft = np.array([f[0] for f in feedback[gid]])
        if len(ft) > 2:
            rates.append((len(ft) - 1) / (ft[-1] - ft[0]))
            gaps.extend(np.diff(ft).tolist())
    replies = [r[1] - r[0] for r in runs]
    print(f"akarm serve's FollowJointTrajectory action, {config.name}, {config.rate_hz:g} Hz loop, {args.distro} "
          f"layouts, {len(runs)} goals of {args.duration:g} s moving {jt.name}; load average "
          f"{load0[0]:.1f} before, {load1[0]:.1f} after ({os.cpu_count()} cores)")
    print(commanded)
    print(f"send_goal sent -> first command frame of the new motion: {percentiles(onsets)} "
          f"(torque step over {threshold:.3f} N·m)")
    print(f"send_goal sent -> its reply received: {percentiles(replies)}")
    print(f"motion's end (first command at the final position) -> result received: {percentiles(to_result)} "
          f"(includes the arm settling within the goal tolerance; the plan ended {np.median(settle):.3f} s after "
          "sending, median)")
    print(f"feedback while a goal runs: {np.median(rates):.1f} messages/s median (min {min(rates):.1f}); gaps "
          f"{percentiles(gaps)}")


if __name__ == "__main__":
    main()
