"""Latency through `akarm serve`: ROS 2 message in → CAN frame out, and CAN reply in → joint_states out.

    .venv/bin/python benchmarks/bench_serve_latency.py [--seconds 20] [--robot robots/arm6.yaml]

Three processes, as on a robot: the simulated drivers (`akarm sim`, akarm_local bus), `akarm serve`,
and this one, which is both a ROS 2 node (Cyclone DDS on the loopback interface) and a listener on
the CAN bus. Times are wall-clock (`time.time()`): a frame's time is when its sender wrote it to the
bus, a DDS sample's when this process woke up with it.

- trajectory → command: a JointTrajectory is published; the first command frame that carries the
  new motion is the first one whose torque field (inverse-dynamics feed-forward of the new plan's
  acceleration, which steps at once where position and velocity change only with t³ and t²)
  differs from the frame before by more than the noise measured while holding.
- reply → joint_states: while the arm moves, every reply carries a new position; each joint_states
  message is matched with the last reply frame that carried its first joint's position exactly.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import can
import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from cyclonedds.core import ReadCondition, WaitSet  # noqa: E402

from akarm.config import JointConfig  # noqa: E402
from akarm.protocol import mit  # noqa: E402
from akarm.robotfile.load import load_robot  # noqa: E402
from akarm.ros import dds, msgs  # noqa: E402
from akarm.sim.process import SimulatorProcess  # noqa: E402


def percentiles(x: list[float]) -> str:
    a = np.array(x) * 1e3
    return f"n {len(a)}, median {np.median(a):.2f} ms, p99 {np.percentile(a, 99):.2f} ms, max {a.max():.2f} ms"


class Frames:
    """Every frame on the bus, with its sender's timestamp, recorded by a thread."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface="akarm_local", channel=channel)
        self.frames: list[can.Message] = []
        self.running = True
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while self.running:
            m = self.bus.recv(0.05)
            if m is not None:
                self.frames.append(m)

    def close(self) -> None:
        self.running = False
        self.thread.join()
        self.bus.shutdown()


class States:
    """joint_states as they arrive here (a WaitSet wakes this thread at once)."""

    def __init__(self, node: dds.Node) -> None:
        self.reader = node.subscription("joint_states", msgs.JointState, depth=1000)
        self.ws = WaitSet(node.participant)
        self.ws.attach(ReadCondition(self.reader, dds.ANY))
        self.received: list[tuple[float, list[float]]] = []
        self.running = True
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        while self.running:
            self.ws.wait(50_000_000)
            now = time.time()
            for m in self.reader.take(100):
                if m.sample_info.valid_data:
                    self.received.append((now, list(m.position)))

    def close(self) -> None:
        self.running = False
        self.thread.join()


def command_onsets(frames: list[can.Message], joint: JointConfig, sent: list[float]) -> tuple[list[float], float, str]:
    """For each time in ``sent`` (a new motion asked for, from rest), how long until the first command
    frame to ``joint`` that carries it: the first whose torque field (the inverse-dynamics
    feed-forward of the new plan's acceleration, which moves at once where position and velocity
    change only with t³ and t²) differs from the 100 ms before by more than 3x the largest deviation
    seen while holding. Also the threshold (N·m) and a line on the commands seen."""
    cmds = [(m.timestamp, mit.decode_command(joint.motor, bytes(m.data))) for m in frames
            if m.arbitration_id == joint.can_id and not m.is_extended_id and mit.special_frame(bytes(m.data)) is None]
    t = np.array([c[0] for c in cmds])
    tau = np.array([c[1].torque for c in cmds])

    def deviation(p: float, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
        """Frames from p+lo to p+hi, and how far their torque is from the median of the 100 ms before p."""
        before = tau[(t > p - 0.1) & (t < p)]
        base = np.median(before) if len(before) else np.nan
        sel = (t > p + lo) & (t < p + hi)
        return t[sel], np.abs(tau[sel] - base)

    span = t[-1] - t[0] if len(t) > 1 else float("nan")
    line = f"{len(cmds)} commands to {joint.name} in {span:.1f} s ({len(cmds) / span:.0f}/s; fewer than the loop's " \
           "rate means a loaded machine)"
    sent = [p for p in sent if len(deviation(p, -0.1, 0.0)[1]) >= 5]  # a stalled machine: no baseline
    quiet = max(deviation(p, -0.1, 0.0)[1].max() for p in sent)
    threshold = max(3.0 * quiet, 0.02)
    onsets = []
    for p in sent:
        tt, dev = deviation(p, 0.0, 0.1)
        hit = np.nonzero(dev > threshold)[0]
        if len(hit):
            onsets.append(tt[hit[0]] - p)
    return onsets, threshold, line


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robot", default=str(ROOT / "robots" / "arm6.yaml"))
    ap.add_argument("--trajectories", type=int, default=40, help="trajectory messages to time")
    ap.add_argument("--joint", type=int, default=1, help="the joint the trajectories move (default 1, arm6's "
                    "shoulder_lift: the most inertia, so the clearest torque step)")
    ap.add_argument("--between", type=float, nargs=2, default=(0.2, 0.6), metavar=("A", "B"),
                    help="the trajectories go back and forth between these positions, rad")
    args = ap.parse_args()
    os.environ["CYCLONEDDS_URI"] = dds.LOOPBACK_CONFIG
    channel, ns, domain = f"bench-serve-{os.getpid()}", f"bench{os.getpid()}", 100 + os.getpid() % 100
    config = load_robot(args.robot)
    j0 = config.joints[0]  # joint_states are matched on the first joint's position
    jt = config.joints[args.joint]
    with SimulatorProcess(args.robot, channel=channel):
        serve = subprocess.Popen([sys.executable, "-m", "akarm", "serve", args.robot, "-i", "akarm_local", "-c",
                                  channel, "--domain", str(domain), "--namespace", ns,
                                  "--feedback-timeout", "0.5"],  # a stall of the shared machine must not stop it
                                 stdout=subprocess.PIPE,
                                 text=True)
        try:
            assert serve.stdout is not None and serve.stdout.readline().startswith("serving"), "serve did not start"
            node = dds.Node(domain, ns)
            writer = node.publisher("joint_trajectory", msgs.JointTrajectory)
            states = States(node)
            frames = Frames(channel)
            while not writer.get_matched_subscriptions():
                time.sleep(0.01)
            time.sleep(1.0)
            names = list(config.joint_names)
            published: list[float] = []
            # back and forth, with the first joint: each message starts a new motion from rest
            for k in range(args.trajectories):
                target = args.between[k % 2]
                msg = msgs.JointTrajectory(msgs.Header(), [names[0], names[args.joint]], [msgs.JointTrajectoryPoint(
                    [target, target], time_from_start=msgs.Duration(0, 800_000_000))])
                time.sleep(0.25 + 0.05 * np.random.rand())  # at rest, holding; a random phase to the loop
                published.append(time.time())
                writer.write(msg)
                time.sleep(1.0)
            time.sleep(0.2)
            frames.close()
            states.close()
            node.close()
        finally:
            serve.terminate()
            serve.wait(30)

    # -- trajectory → first command frame of the new motion ----------------------------------------
    to_frame, threshold, commanded = command_onsets(frames.frames, jt, published)
    print(commanded)
    # -- reply → joint_states ----------------------------------------------------------------------
    replies = [(m.timestamp, mit.decode_reply(j0.motor, bytes(m.data))) for m in frames.frames
               if not m.is_extended_id and m.arbitration_id == j0.reply_id and len(m.data) >= 6
               and m.data[0] == j0.can_id]
    rt = np.array([r[0] for r in replies])
    rq = np.array([j0.direction * r[1].position + j0.offset for r in replies])
    to_states = []
    for when, q in states.received:
        recent = np.nonzero((rq == q[0]) & (rt <= when) & (rt > when - 0.1))[0]
        if 1 <= len(recent) <= 2:  # a position only the last reply or two carried: the arm was moving
            to_states.append(when - rt[recent[-1]])
    print(f"akarm serve latency, {config.name}, {config.rate_hz:g} Hz loop, "
          f"{len(to_frame)} trajectories, {len(states.received)} joint_states")
    print(f"trajectory published -> first command frame of the new motion: {percentiles(to_frame)} "
          f"(joint {jt.name}; torque step over {threshold:.3f} N·m, 3x the largest while holding)")
    print(f"reply on the bus -> joint_states received (arm moving): {percentiles(to_states)}")


if __name__ == "__main__":
    main()
