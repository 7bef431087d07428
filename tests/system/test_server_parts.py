"""The server's parts on their own: the bus registry, the CLI's control socket, the frontends."""

from __future__ import annotations

import _thread
import fcntl
import os
import signal
import subprocess
import sys
import threading
import time

import pytest

import akarm
from akarm.buses import ownership as registry
from akarm.errors import AkarmError, ArgumentError, LimitError, MotorFault, StateError
from akarm.server.server import ArmServerCore
from akarm.server.socket import SocketClient, SocketServer
from akarm.sim import SimulatedRobot
from akarm.sim.process import SimulatorProcess

from .conftest import ROBOTS, relaxed_robot, wait_until


def config_on(channel: str, interface: str = "akarm_local"):
    return akarm.load_robot(ROBOTS / "planar2.yaml").with_bus(interface=interface, channel=channel)


def test_a_bus_lock_is_exclusive_across_processes_and_gone_with_its_holder(channel):
    config = config_on(channel)
    assert registry.find_server(config) is None
    holder = subprocess.Popen([sys.executable, "-c", f"""
import sys, akarm
from akarm.buses.ownership import BusLock
lock = BusLock(akarm.load_robot({str(ROBOTS / 'planar2.yaml')!r}).with_bus(interface="akarm_local",
               channel={channel!r}), {{"robot": "planar2", "socket": "/nowhere"}})
print("locked", flush=True)
sys.stdin.readline()
"""], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "locked"
        info = registry.find_server(config)
        assert info is not None and info["pid"] == holder.pid and info["socket"] == "/nowhere"
        with pytest.raises(StateError, match=f"pid {holder.pid}.*two controllers"):
            registry.BusLock(config, {"robot": "again"})
        with pytest.raises(StateError, match="opening this Arm would be a second controller"):
            akarm.Arm(config).open()
    finally:
        holder.kill()  # no clean exit: the kernel drops the lock anyway
        holder.wait()
    assert registry.find_server(config) is None
    lock = registry.BusLock(config, {"robot": "mine"})
    try:
        assert registry.find_server(config) is None, "this process's own server does not count"
    finally:
        lock.release()


def test_a_released_bus_lock_leaves_no_file_and_a_stale_one_is_not_taken_for_the_bus(channel):
    config = config_on(channel)
    (path,) = [registry.lock_path(k) for k in registry.bus_keys(config)]
    lock = registry.BusLock(config, {"robot": "mine"})
    stale = os.open(path, os.O_RDONLY)  # a process that opened the file to wait for it
    try:
        assert path.exists()
        lock.release()
        assert not path.exists(), "the lock file is removed with the lock"
        fcntl.flock(stale, fcntl.LOCK_EX | fcntl.LOCK_NB)  # it gets the lock of the removed file ...
        again = registry.BusLock(config, {"robot": "again"})  # ... which holds no bus: the next server's file is new
        try:
            assert path.exists() and registry.find_server(config) is None
            with pytest.raises(StateError, match="two controllers"):
                registry.BusLock(config, {"robot": "third"})
        finally:
            again.release()
    finally:
        os.close(stale)
    assert not path.exists()


def test_a_server_that_ends_removes_its_lock_files(tmp_path, channel):
    robot = relaxed_robot(ROBOTS / "planar2.yaml", tmp_path)
    config = akarm.load_robot(robot).with_bus(interface="akarm_local", channel=channel)
    paths = [registry.lock_path(k) for k in registry.bus_keys(config)]
    assert paths
    with SimulatorProcess(robot, channel=channel, pose="down"):
        serve = subprocess.Popen([sys.executable, "-m", "akarm", "serve", str(robot), "-i", "akarm_local", "-c",
                                  channel, "--no-ros"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        try:
            lines = [serve.stdout.readline()]  # type: ignore[union-attr]
            while lines[-1] and not lines[-1].startswith("serving"):
                lines.append(serve.stdout.readline())  # type: ignore[union-attr]
            assert all(p.exists() for p in paths), "".join(lines)
            serve.send_signal(signal.SIGTERM)
            assert serve.wait(60) == 0
        finally:
            if serve.poll() is None:
                serve.kill()
                serve.wait()
    assert not any(p.exists() for p in paths), "the lock files went with the server"


def test_virtual_buses_are_never_locked(channel):
    assert registry.bus_keys(config_on(channel, "virtual")) == []
    assert registry.bus_keys(config_on("vcan0", "socketcan")) == ["socketcan-vcan0"]


def test_the_control_socket_carries_results_and_the_servers_errors(tmp_path):
    def dispatch(op, args, client):
        if op == "add":
            return args["a"] + args["b"]
        if op == "limit":
            raise LimitError("past the range", joint="elbow", fix="a smaller target")
        if op == "fault":
            raise MotorFault("over-temperature", code=1, joint="elbow", fix="let it cool")
        raise KeyError(op)

    server = SocketServer(tmp_path / "c.sock", dispatch)
    try:
        with SocketClient(tmp_path / "c.sock", timeout=10) as c:
            assert c.call("add", a=2, b=3) == 5
            with pytest.raises(LimitError) as e:
                c.call("limit")
            assert (e.value.joint, e.value.fix) == ("elbow", "a smaller target")
            assert str(e.value) == str(LimitError("past the range", joint="elbow", fix="a smaller target"))
            with pytest.raises(MotorFault, match="over-temperature") as fault:  # its class, text and attributes
                c.call("fault")
            assert fault.value.code == 1 and str(fault.value) == "joint 'elbow': over-temperature (fix: let it cool)"
            with pytest.raises(AkarmError, match="akarm serve failed on this request") as bug:
                c.call("nonsense")
            assert "KeyError" not in str(bug.value) and "nonsense" not in str(bug.value), "a bug's text stays inside"
            assert c.call("add", a=1, b=1) == 2, "the connection survives an error"
    finally:
        server.close()
    assert not (tmp_path / "c.sock").exists()
    with pytest.raises(StateError, match="cannot reach akarm serve"):
        SocketClient(tmp_path / "c.sock")


def test_an_answer_left_by_a_call_cut_short_is_not_taken_by_the_next_call(tmp_path):
    """Ctrl-C while a call waits leaves the server's answer on the socket: the next call must skip it
    (it took `False` for a recording, and the path was lost)."""
    release = threading.Event()
    left = []

    def dispatch(op, args, client):
        if op == "slow":
            release.wait(10)
            return "the slow call's answer"
        return {"echo": op, "client": client}

    server = SocketServer(tmp_path / "c.sock", dispatch, closed=left.append)
    try:
        with SocketClient(tmp_path / "c.sock", timeout=10) as c:
            timer = threading.Timer(0.2, lambda: (release.set(), _thread.interrupt_main()))
            timer.start()
            with pytest.raises(KeyboardInterrupt):
                c.call("slow")  # cut short: its answer arrives after the interrupt
            timer.join()
            first = c.call("first")
            assert first["echo"] == "first"  # not "the slow call's answer"
            assert c.call("second")["echo"] == "second"
            client = first["client"]
        with SocketClient(tmp_path / "c.sock", timeout=10) as other:
            assert other.call("x")["client"] != client  # each connection has its own number
        deadline = time.monotonic() + 5
        while len(left) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
        assert client in left and len(left) == 2  # the server hears when each connection ends
    finally:
        server.close()


def test_sockets_of_servers_that_are_gone_are_swept_and_live_ones_kept(monkeypatch, tmp_path):
    monkeypatch.setattr(registry, "BASE", tmp_path)
    runtime = registry.runtime_dir()
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    gone = runtime / f"serve-{dead.pid}-7f00.sock"
    alive = runtime / f"serve-{os.getpid()}-7f01.sock"
    other = runtime / "serve-akarm_local-can0.lock"
    for p in (gone, alive, other):
        p.write_text("")
    assert registry.sweep_sockets() == 1
    assert not gone.exists() and alive.exists() and other.exists()


def test_server_rates_must_be_positive(channel):
    config = akarm.load_robot(ROBOTS / "planar2.yaml").with_bus(interface="virtual", channel=channel)
    with SimulatedRobot(config) as sim, akarm.Arm(config) as arm:
        del sim
        for bad in ({"joint_states_hz": 0}, {"joint_states_hz": -5.0}, {"status_hz": float("nan")}):
            with pytest.raises(ArgumentError, match="must be a positive number of Hz"):
                akarm.ArmServer(arm, ros=False, **bad)
        assert not arm.enabled  # refused before anything was opened or enabled


def test_a_dds_configuration_cyclone_cannot_use_is_an_akarm_error(monkeypatch, channel):
    pytest.importorskip("cyclonedds")
    from akarm.ros.node import RosNode

    config = akarm.load_robot(ROBOTS / "planar2.yaml").with_bus(interface="virtual", channel=channel)
    monkeypatch.setenv("CYCLONEDDS_URI", "<CycloneDDS><Domain><General><Interfaces>"
                                         "<NetworkInterface name='no-such-nic0'/></Interfaces></General>"
                                         "</Domain></CycloneDDS>")
    with SimulatedRobot(config) as sim, akarm.Arm(config) as arm:
        del sim
        server = akarm.ArmServer(arm, ros=False)
        with pytest.raises(AkarmError, match="Cyclone DDS could not start") as e:
            RosNode(server, 77, "", 10.0, 1.0)
        assert "CYCLONEDDS_URI" in e.value.fix


class RecordingFrontend:
    """A frontend that notes when it is made, started and stopped, and whether the arm was enabled then."""

    def __init__(self, server: ArmServerCore, seen: list[tuple[str, bool]]) -> None:
        self.arm = server.arm
        self.seen = seen
        seen.append(("made", self.arm.enabled))

    def start(self) -> None:
        self.seen.append(("started", self.arm.enabled))

    def stop(self) -> None:
        self.seen.append(("stopped", self.arm.enabled))


def test_a_frontend_is_made_before_enabling_started_once_held_and_stopped_once_disabled(channel):
    config = config_on(channel, "virtual")
    seen: list[tuple[str, bool]] = []
    with SimulatedRobot(config) as sim, akarm.Arm(config) as arm:
        del sim
        with ArmServerCore(arm, frontends=[lambda server: RecordingFrontend(server, seen)]) as server:
            assert server.mode == "holding" and seen == [("made", False), ("started", True)]
        assert seen == [("made", False), ("started", True), ("stopped", False)]


def test_a_frontend_that_cannot_be_made_fails_the_start_before_anything_is_enabled(channel):
    def broken(server: ArmServerCore) -> RecordingFrontend:
        raise AkarmError("this frontend has no transport", fix="install it")

    config = config_on(channel, "virtual")
    seen: list[tuple[str, bool]] = []
    with SimulatedRobot(config) as sim, akarm.Arm(config) as arm:
        del sim
        server = ArmServerCore(arm, frontends=[lambda server: RecordingFrontend(server, seen), broken])
        with pytest.raises(AkarmError, match="this frontend has no transport"):
            server.start()
        assert not arm.enabled
        assert seen == [("made", False), ("stopped", False)], "the one made is stopped, never started"


def test_without_cyclone_dds_serving_ros_is_refused_before_anything_is_enabled(monkeypatch, channel):
    for name in [m for m in sys.modules if m == "akarm.ros" or m.startswith("akarm.ros.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "cyclonedds", None)  # as if the ros extra were not installed
    config = config_on(channel, "virtual")
    with SimulatedRobot(config) as sim, akarm.Arm(config) as arm:
        del sim
        server = akarm.ArmServer(arm)
        with pytest.raises(AkarmError, match="need Cyclone DDS's Python binding, which is not installed") as e:
            server.start()
        assert "--no-ros" in e.value.fix and not arm.enabled
        with akarm.ArmServer(arm, ros=False) as served:  # the CLI alone needs no DDS
            assert served.mode == "holding"


def test_an_unknown_ros_distro_or_a_bad_controller_name_fails_the_start_before_anything_is_enabled(channel):
    pytest.importorskip("cyclonedds")
    config = config_on(channel, "virtual")
    with SimulatedRobot(config) as sim, akarm.Arm(config) as arm:
        del sim
        for options, text in (({"ros_distro": "iron"}, "unknown ROS 2 distribution 'iron'"),
                              ({"controller": "arm-1"}, "not a valid ROS 2 name"),
                              ({"node_name": "9lives"}, "not a valid ROS 2 name")):
            server = akarm.ArmServer(arm, domain=77, **options)
            with pytest.raises(AkarmError, match=text):
                server.start()
            assert not arm.enabled


def test_the_snapshot_operation_reads_the_arm_and_takes_no_arguments(channel, tmp_path):
    from akarm.server.snapshot import Snapshot

    # (the relaxed supervisor: an in-process simulator on 2 loaded cores may answer late)
    config = akarm.load_robot(relaxed_robot(ROBOTS / "planar2.yaml", tmp_path)).with_bus(interface="virtual",
                                                                                         channel=channel)
    with SimulatedRobot(config) as sim, akarm.Arm(config) as arm, ArmServerCore(arm) as server:
        assert wait_until(lambda: arm.observe.loop.stats.cycles > 50, 10)
        truth = [s.position for s in sim.driver_states()]
        with SocketClient(server.socket_path, timeout=10) as c:
            snap = Snapshot.from_doc(c.call("snapshot"))
            assert snap.names == tuple(config.joint_names) and snap.mode == "holding" and snap.enabled
            assert snap.stop == "" and snap.rate_hz == config.rate_hz and snap.cycles > 50
            assert snap.missed_slots >= 0 and snap.loop_rate_hz > 0
            assert all(abs(m - t) < 1e-2 for m, t in zip(snap.q, truth, strict=True))
            assert all(abs(a) < 1.0 for a in snap.age), snap.age  # fresh (the loaded CI machine: not exactly 0)
            assert snap.error == pytest.approx([d - m for d, m in zip(snap.q_des, snap.q, strict=True)])
            with pytest.raises(ArgumentError, match="has no argument 'joint'"):
                c.call("snapshot", joint="elbow")
        server.dispatch("disable", {})
        assert server.snapshot().mode == "disabled" and not server.snapshot().enabled


def _in_thread(fn, *args):
    """Run ``fn(*args)`` in a daemon thread; what it returned or raised lands in the list returned."""
    out: list[object] = []

    def run() -> None:
        try:
            out.append(fn(*args))
        except BaseException as e:  # (handed to the test)
            out.append(e)

    th = threading.Thread(target=run, daemon=True)
    th.start()
    return th, out


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="FIFOs are POSIX")
def test_a_replay_of_a_file_that_never_ends_keeps_no_request_and_no_stop_waiting(channel, tmp_path):
    """A FIFO whose writer never writes: the replay's read waits, and only it. Other requests are answered,
    and the server's stop damps and disables the arm at once (it used to wait for that read for ever,
    the motors powered, deaf to SIGTERM and Ctrl-C)."""
    fifo = tmp_path / "never.yaml"
    os.mkfifo(fifo)
    writer = os.open(fifo, os.O_RDWR)  # a writer that never writes (O_RDWR: opening does not wait)
    config = config_on(channel, "virtual")
    try:
        with SimulatedRobot(config) as sim, akarm.Arm(config) as arm:
            del sim
            server = ArmServerCore(arm).start()
            try:
                replay, replayed = _in_thread(server.dispatch, "replay", {"path": str(fifo)})
                time.sleep(0.3)
                assert replay.is_alive(), replayed  # it is reading the FIFO
                status, answered = _in_thread(server.dispatch, "status", {})
                status.join(5.0)
                assert answered and answered[0]["mode"] == "holding"
            finally:
                t0 = time.monotonic()
                server.stop()
                took = time.monotonic() - t0
            assert not arm.enabled and took < 3.0, took
    finally:
        os.close(writer)  # the read ends (empty file)
    replay.join(5.0)
    assert replayed and isinstance(replayed[0], AkarmError), replayed


def test_the_stop_disables_the_arm_at_once_while_a_command_still_runs(channel, monkeypatch):
    """A command that holds the server (a long plan being made) does not keep the motors powered when the
    server stops: it disables the arm after half a second, and again once the command is done."""
    config = config_on(channel, "virtual")
    entered, release = threading.Event(), threading.Event()
    with SimulatedRobot(config) as sim, akarm.Arm(config) as arm:
        del sim
        move_to = arm.move_to

        def slow_move_to(*args, **kwargs):
            entered.set()
            release.wait(30.0)
            return move_to(*args, **kwargs)

        monkeypatch.setattr(arm, "move_to", slow_move_to)
        server = ArmServerCore(arm).start()
        move, moved = _in_thread(server.dispatch, "move", {"target": [0.1, 0.1]})
        assert entered.wait(10.0)
        stop, _ = _in_thread(server.stop)
        assert wait_until(lambda: not arm.enabled, 3.0), "the arm stays enabled while the command runs"
        assert stop.is_alive()  # it waits for the command, to disable again after it
        release.set()
        stop.join(10.0)
        move.join(10.0)
        assert not stop.is_alive() and not arm.enabled
        assert moved and isinstance(moved[0], AkarmError), moved  # refused: the arm was disabled under it


def test_a_stop_is_latched_once_and_an_acknowledged_one_never_again(channel, tmp_path):
    """Each request that reports the latched stop raised a copy of it, and each copy was latched as a new
    stop (a new number, a new log line); after an acknowledgement, waiting for the motion that stop ended
    latched it again, refusing every motion until a second enable."""
    from akarm.errors import FeedbackTimeout
    from akarm.sim import faults

    config = akarm.load_robot(relaxed_robot(ROBOTS / "planar2.yaml", tmp_path)).with_bus(interface="virtual",
                                                                                         channel=channel)
    said: list[str] = []
    with SimulatedRobot(config) as sim, akarm.Arm(config) as arm, \
            ArmServerCore(arm, log=said.append) as server:
        motion = server.dispatch("move", {"target": [0.3, 0.3], "speed": 0.2})
        sim.joint("elbow").inject(faults.Unplugged())
        with pytest.raises(FeedbackTimeout):
            server.dispatch("wait", {"id": motion["id"]})
        assert server.latched is not None and server.latched.seq == 1
        for _ in range(3):
            with pytest.raises(FeedbackTimeout):
                server.dispatch("sleep", {"seconds": 0.1})
        assert server.latched.seq == 1
        assert len([s for s in said if "safety stop (FeedbackTimeout)" in s]) == 1, said
        sim.clear_faults()
        server.dispatch("enable", {})  # acknowledged
        assert server.latched is None
        with pytest.raises(FeedbackTimeout):  # the old motion: the stop that ended it, raised again
            server.dispatch("wait", {"id": motion["id"]})
        server.dispatch("stop", {})  # (what a served verb's Ctrl-C sends: it waits for the stored motions)
        assert server.latched is None and server.mode == "holding"
        server.dispatch("move", {"target": [0.0, 0.0]})  # not refused


def test_after_a_gripper_stop_the_served_gripper_and_servoing_are_refused_until_an_enable(channel, tmp_path):
    """A stop of the gripper's motor latches as an arm's does: gripper_move and servo_twist are refused,
    naming it, and nothing is enabled again until an enable acknowledges it."""
    from akarm.errors import StopLatched
    from akarm.sim import faults

    config = akarm.load_robot(relaxed_robot(ROBOTS / "arm6g.yaml", tmp_path)).with_bus(interface="virtual",
                                                                                       channel=channel)
    with SimulatedRobot(config, q0=config.pose("ready")) as sim, akarm.Arm(config) as arm, \
            ArmServerCore(arm) as server:
        server.dispatch("servo_twist", {"twist": [0.02, 0.0, 0.0, 0.0, 0.0, 0.0]})
        sim.joint("gripper").inject(faults.ErrorCode(2))
        with pytest.raises(MotorFault):
            server.dispatch("sleep", {"seconds": 0.2})
        assert server.latched is not None and not arm.enabled
        for op, args in (("gripper_move", {"width": 0.05, "wait": False}),
                         ("servo_twist", {"twist": [0.02, 0.0, 0.0, 0.0, 0.0, 0.0]})):
            with pytest.raises(StopLatched, match="MotorFault"):
                server.dispatch(op, args)
        assert not arm.enabled and server.latched is not None
