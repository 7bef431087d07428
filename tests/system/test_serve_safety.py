"""`akarm serve` never hides a stop and never re-enables on its own; its status is fresh.

The simulator runs in its own process on `akarm_local` with its control channel (faults, frames);
`akarm serve` in another (ROS 2 on, over loopback, in this run's domain); the CLI verbs as processes
of their own; this test process is also a ROS 2 participant.

- A stop reaches the client: a fault during a served `move` (an unplugged joint; a collision: a
  joint blocked), `teach` or `enable --seconds` makes that verb exit 1 naming the error.
- The stop latches: the next served `move`, `teach` and a ROS 2 trajectory are refused, and nothing
  moves (the simulator's frames: no ENTER, no command with kp > 0); `akarm status` and the ROS 2
  diagnostics show it; after `akarm enable`, a move arrives. Over ROS 2, `akarm/hold` is refused,
  `akarm/disable` leaves the stop latched, and `akarm/enable` acknowledges it.
- Refusals keep no memory: the server's RSS stays flat over thousands of them.
- Status: after a served `disable` the arm falls; `status --json` then matches the simulator's
  positions within 1 mrad, each joint with its age.
"""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml

pytest.importorskip("cyclonedds")

from akarm.buses.ownership import find_server
from akarm.protocol import mit
from akarm.robotfile.load import load_robot
from akarm.ros import dds, msgs
from akarm.server.socket import SocketClient
from akarm.sim import faults
from akarm.sim.process import SimulatorProcess

from .conftest import ROBOTS, relaxed_robot, wait_until
from .test_serve import Served, Watch, unique

pytestmark = pytest.mark.slow


class Stack:
    """The simulator, the server, a ROS 2 participant, and the CLI's arguments for this robot."""

    def __init__(self, robot: Path, channel: str, sim: SimulatorProcess, server: Served, watch: Watch) -> None:
        self.robot, self.channel, self.sim, self.server, self.watch = robot, channel, sim, server, watch
        self.config = load_robot(robot)
        info = find_server(self.config.with_bus(interface="akarm_local", channel=channel))
        assert info is not None
        self.socket = str(info["socket"])
        self.bus = [str(robot), "-i", "akarm_local", "-c", channel]

    def cli(self, verb: str, *args: str, stdin: str | None = None,
            timeout: float = 90.0) -> subprocess.CompletedProcess[str]:
        return subprocess.run([sys.executable, "-m", "akarm", verb, *self.bus, *args], input=stdin,
                              capture_output=True, text=True, timeout=timeout)

    def popen(self, verb: str, *args: str) -> subprocess.Popen[str]:
        return subprocess.Popen([sys.executable, "-m", "akarm", verb, *self.bus, *args], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)

    def call(self, op: str, **args: object) -> dict:
        with SocketClient(self.socket, timeout=60) as c:
            return c.call(op, **args)  # type: ignore[no-any-return]

    def fresh(self) -> None:
        """No fault in the simulator, no stop latched, the arm held at ``down`` (hanging, no gravity torque)."""
        self.sim.control.clear_faults()  # type: ignore[union-attr]
        self.move("down")

    def move(self, target: str) -> None:
        """A served ``move`` to ``target``, enabled first. A stop of a loaded machine on the way (a real-time
        loop that did not run for 0.5 s) is acknowledged and the move tried again, twice at most: the tests
        are about what a stop does, not about the load."""
        for _ in range(3):
            if self.call("status")["stop"] is not None or not self.call("state", read=False)["enabled"]:
                self.call("enable")
            out = self.cli("move", target)
            if out.returncode == 0:
                return
        raise AssertionError(out.stderr + self.log())

    def stopped(self) -> dict:
        """Wait for the latched stop and for the arm to be disabled (damped, then exited); the stop."""
        assert wait_until(lambda: self.call("status")["stop"] is not None
                          and not self.call("state", read=False)["enabled"], 30.0), self.log()
        return self.call("status")["stop"]  # type: ignore[no-any-return]

    def frames_mark(self) -> int:
        return self.sim.control.frames(since=1 << 60)[1]  # type: ignore[union-attr]

    def commands_since(self, mark: int) -> list[tuple[str, bytes]]:
        frames, _ = self.sim.control.frames(since=mark)  # type: ignore[union-attr]
        return [(f.joint, f.data) for f in frames if f.to_motor and f.joint is not None]

    def log(self) -> str:
        return "\nserver:\n" + "".join(self.server.lines[-30:])


@pytest.fixture(scope="module")
def stack(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Stack]:
    folder = tmp_path_factory.mktemp("safety")
    robot = relaxed_robot(ROBOTS / "planar2.yaml", folder)
    doc = yaml.safe_load(robot.read_text())
    for joint, threshold in zip(doc["joints"], (6.0, 3.0), strict=True):  # a collision reflex well above the
        joint["collision"] = {"threshold": threshold}  # torques of a gentle move (even on a loaded machine)
    robot.write_text(yaml.safe_dump(doc))
    channel, ns = unique("safety"), unique("arm")
    with SimulatorProcess(robot, channel=channel, pose="down", control=True) as sim, \
            Served(channel, ns, robot) as server:
        watch = Watch(ns)
        try:
            watch.wait_states()
            yield Stack(robot, channel, sim, server, watch)
        finally:
            watch.close()


def assert_nothing_moved(stack: Stack, mark: int) -> None:
    """No ENTER and no command with stiffness reached a motor since ``mark`` (EXIT queries may have)."""
    models = {j.name: j.motor for j in stack.config.joints}
    for joint, data in stack.commands_since(mark):
        assert mit.special_frame(data) != "enter", f"ENTER sent to {joint}"
        if mit.special_frame(data) is None:
            assert mit.decode_command(models[joint], data).kp == 0.0, f"a command with kp > 0 to {joint}"


def test_an_unplugged_joint_during_a_served_move_stops_it_latches_and_only_enable_clears_it(stack: Stack):
    stack.fresh()
    move = stack.popen("move", "up", "--speed", "0.15")
    assert move.stdout.readline().startswith("moving to up")  # type: ignore[union-attr]
    time.sleep(0.4)
    stack.sim.control.inject("elbow", faults.Unplugged())  # type: ignore[union-attr]
    out, err = move.communicate(timeout=60)
    stop = stack.stopped()
    # the move exits 1, naming the error, with the text a standalone move prints
    assert move.returncode == 1 and "arrived" not in out, out + err
    assert f"akarm move: error: {stop['error']}: {stop['text']}" in err, err + stack.log()
    assert "latched" in err and "akarm enable" in err
    assert stop["error"] in ("FeedbackTimeout", "LoopStall") or stop["joint"] is not None

    time.sleep(1.0)  # joint_states say how old the silent elbow's reading is: stamped with the oldest reading
    received, msg = stack.watch.states[-1]
    stamp = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
    assert time.time() - (time.monotonic() - received) - stamp > 0.8

    mark = stack.frames_mark()
    refused = stack.cli("move", "down")
    assert refused.returncode == 1 and "refused: the arm stopped for safety" in refused.stderr
    assert stop["error"] in refused.stderr and "akarm enable" in refused.stderr
    taught = stack.cli("teach", str(stack.robot.parent / "k.yaml"), stdin="q\n")
    assert taught.returncode == 1 and "refused" in taught.stderr
    before = int(stack.call("status")["trajectories_refused"])
    stack.watch.wait_matched()
    stack.watch.trajectory.write(msgs.JointTrajectory(joint_names=["shoulder", "elbow"], points=[
        msgs.JointTrajectoryPoint(positions=[0.0, 0.0], time_from_start=msgs.Duration(1, 0))]))
    assert wait_until(lambda: int(stack.call("status")["trajectories_refused"]) > before, 10.0), stack.log()
    assert "FeedbackTimeout" in stack.call("status")["last_refusal"] or stop["error"] in \
        stack.call("status")["last_refusal"]
    time.sleep(0.5)  # anything the refused commands might have sent is on the bus by now
    assert_nothing_moved(stack, mark)

    # status shows it (text and JSON), and ROS 2 diagnostics at ERROR
    doc = json.loads(stack.cli("status", "--json").stdout.splitlines()[0])
    assert doc["stop"]["error"] == stop["error"] and doc["stop"]["joint"] == stop["joint"]
    assert doc["stop"]["text"] == stop["text"] and abs(doc["stop"]["time"] - time.time()) < 120
    assert doc["mode"] == "fault" and all(isinstance(j["age"], float) for j in doc["joints"])
    text = stack.cli("status")
    assert "SAFETY STOP latched since" in text.stdout and stop["error"] in text.stdout
    assert wait_until(lambda: stack.watch.status and stack.watch.status[-1].status[0].level == 2, 10.0)
    assert stop["error"] in stack.watch.status[-1].status[0].message

    # acknowledged by an explicit enable only (the cause removed first); then a move arrives
    stack.sim.control.clear_faults()  # type: ignore[union-attr]
    enabled = stack.cli("enable")
    assert enabled.returncode == 0 and "held by akarm serve" in enabled.stdout, enabled.stderr + stack.log()
    assert stack.call("status")["stop"] is None and "acknowledged" in "".join(stack.server.lines)
    acknowledged = time.time()
    moved = stack.cli("move", "down")
    for _ in range(2):  # a new stop of a loaded machine after the acknowledgement (not the one above): again
        new = stack.call("status")["stop"]
        if moved.returncode == 0 or new is None or new["time"] < acknowledged:
            break
        print(f"a new stop on a loaded machine, acknowledged: {new['text']}")
        stack.call("enable")
        moved = stack.cli("move", "down")
    assert moved.returncode == 0 and "arrived" in moved.stdout, moved.stderr + stack.log()


def test_a_collision_during_a_served_move_stops_it_naming_the_collision(stack: Stack):
    stack.fresh()
    move = stack.popen("move", "home", "--speed", "0.3")
    assert move.stdout.readline().startswith("moving to home")  # type: ignore[union-attr]
    time.sleep(0.5)
    stack.sim.control.inject("shoulder", faults.Blocked())  # an obstacle in the way
    out, err = move.communicate(timeout=60)
    stop = stack.stopped()
    assert move.returncode == 1 and "arrived" not in out
    assert f"akarm move: error: {stop['error']}: {stop['text']}" in err, err + stack.log()
    assert stop["error"] in ("CollisionError", "TrackingError"), stop  # the reflex, or the following error
    refused = stack.cli("move", "down")
    assert refused.returncode == 1 and stop["error"] in refused.stderr


def test_over_ros_2_hold_is_refused_and_only_the_enable_service_acknowledges_the_stop(stack: Stack):
    stack.fresh()
    stack.sim.control.inject("elbow", faults.Unplugged())  # type: ignore[union-attr]
    stop = stack.stopped()
    stack.sim.control.clear_faults()  # type: ignore[union-attr]  # the cause removed: still latched
    mark = stack.frames_mark()
    hold, disable, enable = (dds.TriggerClient(stack.watch.node, f"akarm/{name}")
                             for name in ("hold", "disable", "enable"))
    rep = hold.call(timeout=20)
    assert not rep.success and "refused: the arm stopped for safety" in rep.message and stop["error"] in rep.message
    assert disable.call(timeout=20).success  # limp: the stop stays latched
    assert stack.call("status")["stop"] == stop and stack.call("status")["mode"] == "fault"
    time.sleep(0.5)
    assert_nothing_moved(stack, mark)
    rep = enable.call(timeout=20)
    assert rep.success and "holding" in rep.message, rep.message + stack.log()
    status = stack.call("status")
    assert status["stop"] is None and status["mode"] == "holding", status
    assert "acknowledged" in "".join(stack.server.lines[-10:])


@pytest.mark.parametrize("verb", ["teach", "enable"])
def test_a_stop_reaches_a_served_teach_or_enable_seconds_in_progress(stack: Stack, verb: str):
    stack.fresh()
    args = [str(stack.robot.parent / "t.yaml")] if verb == "teach" else ["--seconds", "60"]
    client = stack.popen(verb, *args)
    try:
        assert wait_until(lambda: ("teach" if verb == "teach" else "holding") == stack.call("status")["mode"], 30)
        time.sleep(0.5)
        stack.sim.control.inject("elbow", faults.Unplugged())  # type: ignore[union-attr]
        client.wait(60)  # stdin stays open (its end would end teaching): no keyframe asked for
        out, err = client.communicate()
    finally:
        if client.poll() is None:
            client.kill()
    stop = stack.stopped()
    assert client.returncode == 1, out + err
    assert f"akarm {verb}: error: {stop['error']}: {stop['text']}" in err, err + stack.log()


def rss_kib(pid: int) -> int:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise AssertionError("no VmRSS")


def test_refused_requests_and_trajectories_keep_no_memory(stack: Stack):
    stack.fresh()
    stack.sim.control.inject("elbow", faults.Unplugged())  # type: ignore[union-attr]
    stack.stopped()
    pid = stack.server.proc.pid  # type: ignore[union-attr]
    stack.watch.wait_matched()
    trajectory = msgs.JointTrajectory(joint_names=["elbow"], points=[
        msgs.JointTrajectoryPoint(positions=[0.1], time_from_start=msgs.Duration(1, 0))])

    def refuse(n_socket: int, n_ros: int) -> None:
        with SocketClient(stack.socket, timeout=60) as c:
            for k in range(max(n_socket, n_ros)):
                if k < n_socket:
                    with pytest.raises(Exception, match="refused: the arm stopped for safety"):
                        c.call("move", target="down")
                if k < n_ros:
                    stack.watch.trajectory.write(trajectory)

    refuse(2000, 300)  # warm up: allocator pools, caches, the log's buffers
    time.sleep(1.0)
    refused0, rss0 = int(stack.call("status")["trajectories_refused"]), rss_kib(pid)
    refuse(10000, 2000)
    assert wait_until(lambda: int(stack.call("status")["trajectories_refused"]) >= refused0 + 500, 30)
    time.sleep(1.0)
    grown = rss_kib(pid) - rss0
    # each refusal re-raising the one stored stop grew it ~2 KB: 12000 of them, ~24 MB
    assert grown < 4096, f"RSS grew {grown} KiB over 12000 refusals"
    assert "more refused in the last second" in "".join(stack.server.lines), "a flood is logged, counted"


def test_status_after_a_served_disable_reads_the_motors_with_their_age(stack: Stack):
    """After a served disable the limp arm falls from ``home`` and then creeps (a few mrad/s): ``status
    --json`` must give where the simulated motors are while it reads them, not where they were let go."""
    stack.fresh()
    stack.move("home")  # horizontal: it falls when let go
    out = stack.cli("disable")
    assert out.returncode == 0 and "limp" in out.stdout
    time.sleep(3.0)  # fallen
    seen: list[dict[str, float]] = []
    done = threading.Event()

    def watch_simulator() -> None:  # where the simulated motors are, all the while status runs
        while not done.is_set():
            seen.append({d.name: d.position for d in stack.sim.control.state()})  # type: ignore[union-attr]

    poller = threading.Thread(target=watch_simulator)
    poller.start()
    try:
        status = stack.cli("status", "--json")
    finally:
        done.set()
        poller.join(30)
    assert status.returncode == 0, status.stderr
    doc = json.loads(status.stdout.splitlines()[0])
    assert doc["mode"] == "disabled" and doc["stop"] is None
    for j in doc["joints"]:
        gap = min(abs(j["position"] - s[j["name"]]) for s in seen)
        assert gap < 1e-3, f"{j['name']}: {j['position']:+.4f} rad is {gap * 1e3:.1f} mrad from the simulator"
        assert isinstance(j["age"], float) and 0.0 <= j["age"] < 1.0, j
    assert abs(seen[0]["shoulder"]) > 0.5, "it fell from home: what was heard when it was let go is stale"
    text = stack.cli("status")
    assert "asked with EXIT" in text.stdout and "age (s)" in text.stdout
    stack.call("enable")


def test_a_script_serving_its_arm_gets_the_same_latch(tmp_path: Path):
    """ArmServer in a script: its follow() (what every frontend calls) is refused while a stop is
    latched, refuse_if_latched() says so, and only its enable() acknowledges it."""
    import akarm
    from akarm.errors import StopLatched

    robot = relaxed_robot(ROBOTS / "planar2.yaml", tmp_path)
    channel = unique("script")
    with SimulatorProcess(robot, channel=channel, pose="down", control=True) as sim, \
            akarm.Arm(load_robot(robot).with_bus(interface="akarm_local", channel=channel)) as arm, \
            akarm.ArmServer(arm, ros=False, log=lambda text: None) as server:
        assert server.latched is None
        server.refuse_if_latched()  # nothing latched: nothing raised
        sim.control.inject("elbow", faults.Unplugged())  # type: ignore[union-attr]
        assert wait_until(lambda: server.latched is not None and not arm.enabled, 30.0)
        stop = server.latched
        assert stop is not None and stop.name == "FeedbackTimeout" and stop.error.joint == "elbow"
        errors = []
        for _ in range(3):
            with pytest.raises(StopLatched) as e:
                server.follow(["elbow"], [1.0], [[0.3]])
            errors.append(e.value)
        assert errors[0] is not errors[1] and errors[0].stop == "FeedbackTimeout" and server.counts["refused"] == 3
        with pytest.raises(StopLatched, match="refused: the arm stopped for safety"):
            server.refuse_if_latched()
        server.disable()  # limp: the stop stays latched
        assert server.latched is stop and server.mode == "fault"
        sim.control.clear_faults()  # type: ignore[union-attr]
        server.enable()  # acknowledged, enabled without a kick
        assert server.latched is None and arm.enabled and server.mode == "holding"
        motion = server.follow(["elbow"], [1.0], [[0.3]])
        assert motion is not None
        motion.wait()
        assert abs(arm.state().q[1] - 0.3) < 5e-3
